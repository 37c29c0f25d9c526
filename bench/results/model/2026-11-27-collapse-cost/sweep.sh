#!/bin/bash
# The collapse's triangle cost against the warp model (this folder's README).
# usage: sweep.sh RAYS_DIR OUT   (RAYS_DIR/SCENE.{primary,diffuse}.rays from
#        `cwbvh rays FILE --primary|--diffuse --view 1 --width 640 --height 360`)
# Weights: node 267 (node step 188 + about 68 of iteration control + 11 for the loads),
# triangle 127 (watertight float path 92 + about 35 of round control and loads).
set -euo pipefail
root=$(cd "$(dirname "$0")/../../../.." && pwd)
rays=$1; out=$2; : > "$out"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
for cp in 0.3 0.45 0.6 0.9; do
  for s in sponza_dabrovic oa_oacmpctf3 fg_cg57 oa_dm5 dragon; do
    f=$tmp/$s.$cp.cwbvh
    "$root/build/bin/cwbvhc" "$root/../shared/scenes/$s.glb" --collapse-cost-prim $cp -o "$f" --quiet
    for kind in primary diffuse; do
      line=$("$root/build/bin/cwbvh" model "$f" --rays "$rays/$s.$kind.rays" --node-instructions 267 \
               --tri-instructions 127 2>&1 |
             awk '/^nodes\/ray/{n=$2} /^triangles\/ray/{t=$2} /^lanes\/tri/{lt=$3} /^instr\/ray/{i=$3} END{print n, t, lt, i}')
      echo "$cp $s $kind $line" >> "$out"
    done
    rm -f "$f"
  done
done
