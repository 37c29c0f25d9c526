#!/bin/bash
# Deferred hit distances (issue 18) on the catalog views of the GPU set, by the warp model:
# `cwbvh model --check` with the kernel's deferral (default) and without (--no-defer-hits),
# primary rays and diffuse bounce 1 (this folder's README; the loop, since 2026-11-28:
# bench/model_catalog_sets.sh, the same output lines as this script wrote on 2026-11-27).
# usage: run.sh OUT [WIDTH HEIGHT]   (from a Release build in build/)
set -euo pipefail
root=$(cd "$(dirname "$0")/../../../.." && pwd)
exec "$root/bench/model_catalog_sets.sh" "$1" "${2:-480}" "${3:-270}" \
  "^rays|^nodes/ray|^triangles/ray|^refills|^double path|^deferred|^check" \
  "--no-defer-hits|--no-defer-hits --check" "deferred|--check"
