#!/bin/bash
# The kernel's lane code (fast half node test) against the CPU reference on every catalog view
# of every scene in ../shared/scenes: `cwbvh model --check` (this folder's README).
# usage: run.sh OUT   (from a Release build in build/; scratch files in a temporary folder)
set -euo pipefail
root=$(cd "$(dirname "$0")/../../../.." && pwd)
out=$1; : > "$out"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
cd "$root"
for s in bunny sponza_dabrovic oa_oacmpctf3 oa_dm5 fg_cg57 fg_terrain_iceland fg_truman torcs_forza dragon \
         dragon_res2 dragon_res4 dense_dragons dragon_loop1_draco kicad_board; do
  f=$tmp/$s.cwbvh
  # --flatten: the model traces single-level files (dense_dragons and kicad_board instance meshes).
  build/bin/cwbvhc "../shared/scenes/$s.glb" -o "$f" --quiet --flatten
  for v in $(awk -v s="$s" '$1 == s { print $2 }' views/catalog.txt); do
    for kind in primary diffuse; do
      r=$tmp/rays
      build/bin/cwbvh rays "$f" --$kind --view "$v" --width 480 --height 270 -o "$r" > /dev/null
      res=$(build/bin/cwbvh model "$f" --rays "$r" --check 2>&1 | grep -E "^rays|fast node|^check" | tr '\n' ' ')
      echo "$s $v $kind :: $res" | sed -E 's/ +/ /g' >> "$out"
    done
  done
  rm -f "$f"
done
