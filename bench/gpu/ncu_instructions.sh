#!/usr/bin/env bash
# Executed warp instructions per ray of the CWBVH and BVH2 kernels, by Nsight Compute, on every
# catalog view of the given scenes (issue 18's target: CWBVH <= 0.6x BVH2 per diffuse ray on
# every view). For the GPU machine (ncu from the CUDA toolkit, no other dependency than
# python3): one ncu pass per kernel and ray set, metric smsp__inst_executed.sum of the first
# launch of `cwbvh trace --gpu [--bvh2]` (closest hit, watertight), divided by the ray count
# in the ray file's header. The scenes must hold a BV2L/BVH2 section (cwbvhc --keep-sbvh, as
# scripts/gpu-check.sh compiles them).
#
# usage: bench/gpu/ncu_instructions.sh [--primary] [--size N] SCENE.cwbvh...
# env:   CWBVH=path of the cwbvh tool (default build-gpu/bin/cwbvh, then build/bin/cwbvh)
#        AB=1: also the CWBVH kernel without deferred hit distances (ND) and with the reference
#        node test for every ray (RN), `cwbvh trace --gpu --no-defer-hits | --reference-node-test`:
#        two more profiled runs per view, and their instructions per ray beside the kernel's
#        NCU=path of ncu (default: ncu on PATH, then /usr/local/cuda/bin/ncu)
# output: one line per scene and view, then the worst ratio; exit 0 when every line ran.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
kind=(--diffuse --bounce 1)
label="diffuse bounce 1"
size=1024
while (($#)); do
  case "$1" in
    --primary) kind=(--primary); label="primary"; shift ;;
    --size) size=$2; shift 2 ;;
    -h|--help) sed -n '2,13p' "$0"; exit 0 ;;
    *) break ;;
  esac
done
(($#)) || { echo "usage: $0 [--primary] [--size N] SCENE.cwbvh..." >&2; exit 2; }
cwbvh=${CWBVH:-}
[[ -n "$cwbvh" ]] || for c in "$root/build-gpu/bin/cwbvh" "$root/build/bin/cwbvh"; do [[ -x "$c" ]] && { cwbvh=$c; break; }; done
[[ -x "$cwbvh" ]] || { echo "ncu_instructions: no cwbvh tool (set CWBVH)" >&2; exit 2; }
ncu=${NCU:-$(command -v ncu || echo /usr/local/cuda/bin/ncu)}
[[ -x "$ncu" ]] || { echo "ncu_instructions: no ncu (set NCU)" >&2; exit 2; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Warp instructions executed by the first launch of the kernel whose name matches $1.
instructions() {
  local regex=$1; shift
  "$ncu" --csv --metrics smsp__inst_executed.sum --kernel-name "regex:$regex" --launch-count 1 "$@" 2>/dev/null |
    python3 -c '
import csv, sys
rows = list(csv.reader(sys.stdin))  # the traced program prints its own lines too
head = next((r for r in rows if "Metric Value" in r and "Metric Name" in r), None)
vals = []
if head:
    vi, ni = head.index("Metric Value"), head.index("Metric Name")
    vals = [float(r[vi].replace(",", "")) for r in rows if len(r) == len(head) and r[ni] == "smsp__inst_executed.sum"]
print(int(vals[0]) if vals else "")'
}
ray_count() { python3 -c 'import struct, sys; print(struct.unpack_from("<Q", open(sys.argv[1], "rb").read(32), 16)[0])' "$1"; }

ab=${AB:-0}
if [[ "$ab" == 1 ]]; then
  printf '%-24s %-14s %10s %12s %12s %7s %12s %12s\n' scene view rays "CWBVH/ray" "BVH2/ray" ratio "ND/ray" "RN/ray"
else
  printf '%-24s %-14s %10s %12s %12s %7s\n' scene view rays "CWBVH/ray" "BVH2/ray" ratio
fi
worst=0
for scene in "$@"; do
  stem=$(basename "${scene%.cwbvh}")
  views=$(awk -v s="$stem" '$1 == s { print $2 }' "$root/views/catalog.txt")
  [[ -n "$views" ]] || views=default
  for view in $views; do
    rays="$tmp/$stem-$view.rays"
    vargs=(--view "$view")
    [[ "$view" == default ]] && vargs=()
    "$cwbvh" rays "$scene" "${kind[@]}" --width "$size" --height "$size" "${vargs[@]}" -o "$rays" >/dev/null
    n=$(ray_count "$rays")
    cw=$(instructions 'cwbvh_trace_kernel' "$cwbvh" trace "$scene" --rays "$rays" --gpu)
    b2=$(instructions 'bvh2_trace_kernel' "$cwbvh" trace "$scene" --rays "$rays" --gpu --bvh2)
    nd=0; rn=0
    if [[ "$ab" == 1 ]]; then
      nd=$(instructions 'cwbvh_trace_kernel' "$cwbvh" trace "$scene" --rays "$rays" --gpu --no-defer-hits)
      rn=$(instructions 'cwbvh_trace_kernel' "$cwbvh" trace "$scene" --rays "$rays" --gpu --reference-node-test)
    fi
    if [[ -z "$cw" || -z "$b2" || -z "$nd" || -z "$rn" ]]; then
      echo "ncu_instructions: $stem $view: ncu gave no figure (kernel names, permissions?)" >&2
      exit 1
    fi
    python3 - "$stem" "$view" "$n" "$cw" "$b2" "$nd" "$rn" <<'EOF'
import sys
stem, view = sys.argv[1], sys.argv[2]
n, cw, b2, nd, rn = (int(x) for x in sys.argv[3:8])
line = f"{stem:24s} {view:14s} {n:10d} {cw / n:12.1f} {b2 / n:12.1f} {cw / b2:7.3f}"
if nd or rn:
    line += f" {nd / n:12.1f} {rn / n:12.1f}"
print(line)
EOF
    worst=$(python3 -c "print(max($worst, $cw / $b2))")
  done
done
echo "worst CWBVH/BVH2 executed warp instructions per ray ($label): $worst (issue 18 target <= 0.6)"
