#!/bin/bash
# The worst ray of every catalog set (2026-11-28): on every catalog view of the GPU set's
# scenes, primary rays and diffuse bounce 1, `cwbvh model` with the fast node test (the kernel
# as it is, after 12e7803's |rcp| spread limit) and with the reference node test for every ray;
# the model's worst ray (most node visits plus triangle tests) and its means (this folder's
# README; the loop: bench/model_catalog_sets.sh).
# usage: run.sh OUT [WIDTH HEIGHT]   (from a Release build in build/; the README's table: 640 360)
set -euo pipefail
root=$(cd "$(dirname "$0")/../../../.." && pwd)
exec "$root/bench/model_catalog_sets.sh" "$1" "${2:-640}" "${3:-360}" "worst ray|nodes/ray" \
  "fast|" "ref|--reference-node-test"
