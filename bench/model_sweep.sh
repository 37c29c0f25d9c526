#!/usr/bin/env bash
# Warp-model sweep (no GPU needed): for each scene and view, generates primary and
# diffuse rays with `cwbvh rays` and runs `cwbvh model` for the CWBVH kernel with the
# postponing rule before issue 10 (--postpone-with-node-work), with today's rule
# (instruction weights of the kernel as measured on the H100), with today's rule and
# today's node step (344 instructions by bench/gpu/step_sizes.sh instead of 440), and
# the BVH2 baseline (Aila-Karras-Laine 2012 over BV2L) and the BVH2 2009 kernel that
# issue 10 measured (over a legacy one-triangle-per-leaf BVH2 section when
# LEGACY_CWBVHC names a cwbvhc from before format 1.1, else over BV2L); prints one
# markdown table row per run.
# usage: bench/model_sweep.sh OUT.md [WIDTH]
# env:   CWBVH=path/to/cwbvh  CWBVHC=path/to/cwbvhc  LEGACY_CWBVHC=old cwbvhc (optional)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=$1
w=${2:-1024}
cwbvh=${CWBVH:-$root/build/bin/cwbvh}
cwbvhc=${CWBVHC:-$root/build/bin/cwbvhc}
scenes=${CWBVH_SHARED_SCENES:-$root/../shared/scenes}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# scene file | view of the catalog (views/catalog.txt; the GPU benchmark's views)
views=(
  "sponza_dabrovic.obj|1"
  "oa_oacmpctf3.glb|1"
  "bunny.obj|1"
  "fg_cg57.glb|1"
  "dragon_res2.glb|1"
)
{
  echo "| scene | view | rays | variant | rays | nodes/ray | tris/ray | lanes/node step | lanes/tri step | tri share of steps | est. lanes/instr | est. instr/ray |"
  echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
} > "$out"
for v in "${views[@]}"; do
  IFS='|' read -r file view <<< "$v"
  name=${file%.*}
  [[ -f "$scenes/$file" ]] || { echo "skip $file" >&2; continue; }
  "$cwbvhc" "$scenes/$file" -o "$tmp/$name.cwbvh" --keep-sbvh --quiet
  legacy="$tmp/$name.cwbvh"
  if [[ -n "${LEGACY_CWBVHC:-}" ]]; then
    legacy="$tmp/$name-legacy.cwbvh"
    "$LEGACY_CWBVHC" "$scenes/$file" -o "$legacy" --keep-sbvh --quiet
  fi
  camarg=(--view "$view" --scene "$name")
  for kind in primary d1 d4; do
    case $kind in
      primary) "$cwbvh" rays "$tmp/$name.cwbvh" --primary "${camarg[@]}" --width "$w" --height "$w" -o "$tmp/r" >/dev/null ;;
      d1) "$cwbvh" rays "$tmp/$name.cwbvh" --diffuse --bounce 1 "${camarg[@]}" --width "$w" --height "$w" -o "$tmp/r" >/dev/null ;;
      d4) "$cwbvh" rays "$tmp/$name.cwbvh" --diffuse --bounce 4 "${camarg[@]}" --width "$w" --height "$w" -o "$tmp/r" >/dev/null ;;
    esac
    for variant in "cwbvh old postponing|--postpone-with-node-work" "cwbvh|" "cwbvh, node step 344|--node-instructions 344" \
                   "bvh2 AKL 2012 (BV2L)|--bvh2" "bvh2 2009 (as measured)|--bvh2-2009"; do
      label=${variant%%|*}
      flags=${variant#*|}
      f="$tmp/$name.cwbvh"
      [[ "$flags" == "--bvh2-2009" ]] && f=$legacy
      # shellcheck disable=SC2086
      "$cwbvh" model "$f" --rays "$tmp/r" $flags > "$tmp/m.txt"
      get() { python3 -c 'import sys; k = sys.argv[1]; print(next((l[len(k):].split()[0] for l in open(sys.argv[2]) if l.startswith(k)), ""))' "$1" "$tmp/m.txt"; }
      share=$(grep '^warp steps/ray' "$tmp/m.txt" | sed 's/.*: \([0-9.]*\)% triangle.*/\1/')
      echo "| $name | $view | $kind | $label | $(get rays) | $(get nodes/ray) | $(get triangles/ray) | $(get 'lanes/node step') | $(get 'lanes/tri step') | $share% | $(get 'lanes/instr est') | $(get 'instr/ray est') |" >> "$out"
    done
  done
done
cat "$out"
