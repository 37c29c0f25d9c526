#!/usr/bin/env bash
# Registers, stack and spills of every GPU kernel, without a GPU: compiles the kernel
# translation units with `ptxas -v` for one architecture and writes the report to
# bench/results/ptxas-<arch>.txt (or the path given), one summary line per kernel
# after the raw ptxas output. Issue 10's budget: every production CWBVH kernel at
# most 80 registers on sm_90 with no spill stores.
# --check: write to a temporary file instead and exit 1 unless every production CWBVH
# kernel (the non-counting variants: <test, mode, false, defer>; four with deferred hits,
# the two watertight ones without) has at most 80 registers, no spill stores and a
# stack frame of exactly its spill area (52 entries x 8 B = 416 B: anything more is
# per-ray state that went to local memory, as the stack object once did; issue 18).
# A ctest where nvcc is found.
# usage: scripts/ptxas-report.sh [--check] [ARCH (default sm_90)] [OUT]
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
arch=${1:-sm_90}
out=${2:-$root/bench/results/ptxas-$arch.txt}
if [ "$check" = 1 ]; then out=$(mktemp); trap 'rm -f "$out"' EXIT; fi
nvcc=${CUDACXX:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
{
  echo "# $("$nvcc" --version | tail -2 | head -1)"
  echo "# -std=c++17 -O3 -DNDEBUG -arch=$arch -Xptxas -v; commit $(git -C "$root" rev-parse --short HEAD)$(git -C "$root" diff --quiet -- kernels format || echo '+local changes')"
  for cu in kernels_cwbvh kernels_bvh2 trace_two_level; do
    "$nvcc" -std=c++17 -O3 -DNDEBUG -arch="$arch" -Xptxas -v -I"$root/kernels/include" -I"$root/format/include" \
      -I"$root/loader/include" -c "$root/kernels/src/$cu.cu" -o "$tmp/$cu.o" 2>&1 | c++filt > "$tmp/kernels_$cu.txt"
  done
  echo "#"
  echo "# kernel (TriangleTest 0 watertight / 1 fast, HitMode 0 closest / 1 any, counting variant true/false[, CWBVH: deferred hits true/false]): registers, spill stores/loads, stack frame"
  cat "$tmp"/kernels_*.txt | python3 -c '
import re, sys
name = None
for line in sys.stdin:
    m = re.search(r"Function properties for (?:void )?(.+?)\((?:cwbvh::gpu::)?(?:\(anonymous namespace\)::)?(?:TwoLevel)?LaunchParams\)\s*$", line)
    if m:
        name = m.group(1).replace("cwbvh::gpu::", "").replace("(anonymous namespace)::", "").replace("cwbvh::TriangleTest", "test").replace("cwbvh::HitMode", "mode")
    m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
    if m and name:
        frame, st, ld = m.groups()
    m = re.search(r"Used (\d+) registers", line)
    if m and name:
        print(f"# {name:70s} {m.group(1):>4s} regs  spill {st}/{ld} B  stack {frame} B")
        name = None
'
  echo "#"
  cat "$tmp"/kernels_*.txt
} > "$out"
grep '^# ' "$out" | sed -n '4,$p'
if [ "$check" = 1 ]; then
  grep -E '^# cwbvh_trace_kernel<\(test\)[01], \(mode\)[01], false, (true|false)>' "$out" | python3 -c '
import re, sys
bad = 0
lines = sys.stdin.read().splitlines()
for line in lines:
    m = re.search(r"(\d+) regs\s+spill (\d+)/(\d+) B\s+stack (\d+) B", line)
    regs, st, ld, frame = map(int, m.groups())
    if regs > 80 or st or ld or frame != 416:
        print("FAIL:", line.strip("# ")); bad += 1
if len(lines) != 6: print("FAIL: expected 6 production CWBVH kernels, found", len(lines)); bad += 1
sys.exit(1 if bad else 0)
'
fi
