#!/bin/bash
# What the warp model says of the GPU run's A/Bs (2026-11-28): on every catalog view of the GPU
# set's scenes, primary rays and diffuse bounce 1, `cwbvh model` with the kernel as it is and
# with each variant cwbvh_gpu_check times beside it: --no-defer-hits, --reference-node-test,
# --postpone-percent 10, 35, 50 (this folder's README; the loop: bench/model_catalog_sets.sh).
# usage: run.sh OUT [WIDTH HEIGHT]   (from a Release build in build/)
set -euo pipefail
root=$(cd "$(dirname "$0")/../../../.." && pwd)
exec "$root/bench/model_catalog_sets.sh" "$1" "${2:-480}" "${3:-270}" \
  "^rays|^nodes/ray|^triangles/ray|^lanes/node|^lanes/tri|^warp steps|^double path" \
  "default|" "--no-defer-hits|--no-defer-hits" "--reference-node-test|--reference-node-test" \
  "--postpone-percent=10|--postpone-percent 10" "--postpone-percent=35|--postpone-percent 35" \
  "--postpone-percent=50|--postpone-percent 50"
