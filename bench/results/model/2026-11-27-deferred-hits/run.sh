#!/bin/bash
# Deferred hit distances (issue 18) on the catalog views of the GPU set, by the warp model:
# `cwbvh model --check` with the kernel's deferral (default) and without (--no-defer-hits),
# primary rays and diffuse bounce 1 (this folder's README).
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
      for mode in --no-defer-hits ""; do
        res=$(build/bin/cwbvh model "$f" --rays "$r" $mode --check 2>&1 |
              grep -E "^rays|^nodes/ray|^triangles/ray|^refills|^double path|^deferred|^check" | tr '\n' ' ')
        echo "$s $v $kind ${mode:-deferred} :: $res" | sed -E 's/ +/ /g' >> "$out"
      done
    done
  done
  rm -f "$f"
done
