#!/bin/bash
# What the warp model says of the GPU run's A/Bs (2026-11-28): on every catalog view of the GPU
# set's scenes, primary rays and diffuse bounce 1, `cwbvh model` with the kernel as it is and
# with each variant cwbvh_gpu_check times beside it: --no-defer-hits, --reference-node-test,
# --postpone-percent 10, 35, 50 (this folder's README).
# usage: run.sh OUT [WIDTH HEIGHT]   (from a Release build in build/; scratch in a temporary folder)
set -euo pipefail
root=$(cd "$(dirname "$0")/../../../.." && pwd)
out=$1; w=${2:-480}; h=${3:-270}; : > "$out"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cd "$root"
for s in bunny sponza_dabrovic oa_oacmpctf3 oa_dm5 fg_cg57 dragon dense_dragons dragon_loop1_draco kicad_board; do
  src=../shared/scenes/$s.glb
  [[ -f "$src" ]] || { echo "$s: not in ../shared/scenes, skipped" >> "$out"; continue; }
  f=$tmp/$s.cwbvh
  # --flatten: the model traces single-level files (dense_dragons and kicad_board instance meshes).
  build/bin/cwbvhc "$src" -o "$f" --quiet --flatten
  for v in $(awk -v s="$s" '$1 == s { print $2 }' views/catalog.txt); do
    for kind in primary diffuse; do
      r=$tmp/rays
      build/bin/cwbvh rays "$f" --$kind --view "$v" --width "$w" --height "$h" -o "$r" > /dev/null
      for variant in default --no-defer-hits --reference-node-test "--postpone-percent 10" \
                     "--postpone-percent 35" "--postpone-percent 50"; do
        args=()
        [[ "$variant" != default ]] && read -r -a args <<< "$variant"
        res=$(build/bin/cwbvh model "$f" --rays "$r" "${args[@]}" 2>&1 |
              grep -E "^rays|^nodes/ray|^triangles/ray|^lanes/node|^lanes/tri|^warp steps|^double path" | tr '\n' ' ')
        echo "$s $v $kind ${variant// /=} :: $res" | sed -E 's/ +/ /g' >> "$out"
      done
    done
  done
  rm -f "$f"
done
