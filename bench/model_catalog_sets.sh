#!/bin/bash
# The warp model over the GPU set's catalog ray sets: for each scene of ../shared/scenes (the
# GPU set's nine, as the view catalog keys them), each of its catalog views, primary rays and
# diffuse bounce 1, runs `cwbvh model` once per variant and appends one line per run to OUT:
#   SCENE VIEW KIND LABEL :: <the model's output lines that match GREP, joined>
# Variants are LABEL|ARGS (ARGS: extra `cwbvh model` options, split on spaces; may be empty).
# The studies under bench/results/model/ call it from their run.sh and parse OUT there.
# usage: bench/model_catalog_sets.sh OUT WIDTH HEIGHT GREP 'LABEL|ARGS'...
#        (from a Release build in build/; files are compiled --flatten into a temporary folder)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
(( $# >= 5 )) || { echo "usage: $0 OUT WIDTH HEIGHT GREP 'LABEL|ARGS'..." >&2; exit 2; }
out=$1; w=$2; h=$3; pattern=$4; shift 4
: > "$out"
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
      for variant in "$@"; do
        label=${variant%%|*}
        read -r -a args <<< "${variant#*|}"
        res=$(build/bin/cwbvh model "$f" --rays "$r" "${args[@]}" 2>&1 | grep -E "$pattern" | tr '\n' ' ')
        echo "$s $v $kind $label :: $res" | sed -E 's/ +/ /g' >> "$out"
      done
    done
  done
  rm -f "$f"
done
