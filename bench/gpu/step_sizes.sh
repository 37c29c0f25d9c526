#!/usr/bin/env bash
# SASS instructions per traversal step, without a GPU or a disassembler: compiles
# bench/gpu/step_probe.cu to an sm_90 cubin and prints each probe kernel's .text size
# in 16-byte instructions, minus the empty probe's frame. Code size, not executed
# instructions: every probe also holds the per-ray set-up (probe_ray_setup: subtract
# it), and the watertight triangle test includes its double-precision fallback, a
# branch most tests never take, so its figure is an upper bound (the fast test's
# is close to the watertight float path). The node probe runs in two variants: the
# kernel's common path (intersect_node_fast, node_intersect_fast.h) and the reference
# arithmetic (intersect_node_scalar: rays the fast test does not accept). The last
# lines give each step net of the set-up probe. The NOPs that pad each kernel to 128
# bytes are not counted (sm_90's NOP encoding; on another ARCH the sizes may include them).
# --check: also exit 1 when the kernel-shaped probe's fast path is more than 16
# instructions above the fast probe's (a ctest where nvcc is found).
# usage: bench/gpu/step_sizes.sh [--check] [ARCH, default sm_90]
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
check=0
if [ "${1:-}" = "--check" ]; then check=1; shift; fi
arch=${1:-sm_90}
nvcc=${CUDACXX:-$(command -v nvcc || echo /usr/local/cuda/bin/nvcc)}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$nvcc" -std=c++17 -O3 -DNDEBUG -arch="$arch" -cubin -I"$root/kernels/include" -I"$root/format/include" \
  "$root/bench/gpu/step_probe.cu" -o "$tmp/probe.cubin"
readelf -SW "$tmp/probe.cubin" 2>/dev/null | python3 -c '
import re, struct, subprocess, sys
cubin = open(sys.argv[1], "rb").read()
rows = []
for line in sys.stdin:
    m = re.search(r"\] (\.text\.\S+)\s+\S+\s+\S+\s+([0-9a-f]+)\s+([0-9a-f]+)", line)
    if m:
        off, size = int(m.group(2), 16), int(m.group(3), 16)
        # Drop the NOPs that pad the code to 128 bytes (sm_90 NOP: low word 0x7918).
        while size >= 16 and struct.unpack_from("<Q", cubin, off + size - 16)[0] == 0x7918:
            size -= 16
        rows.append((m.group(1)[len(".text."):], size))
names = subprocess.run(["c++filt"], input="\n".join(n for n, _ in rows), capture_output=True, text=True).stdout.split("\n")
empty = next(s for (n, s) in rows if "probe_empty" in n)
net = {}
for (n, s), d in zip(rows, names):
    if "probe_empty" in n:
        continue
    print(f"{d:75s} {(s - empty) // 16:5d} instructions")
    net[d] = (s - empty) // 16
setup = next(v for k, v in net.items() if "probe_ray_setup" in k)
tri_setup = next(v for k, v in net.items() if "probe_triangle_setup" in k)
for k, v in net.items():
    if "probe_triangle_edges" in k:
        print(f"watertight triangle test, first stage (decides the misses), net of set-up: {v - tri_setup} instructions")
    elif "probe_triangle_range" in k:
        print(f"watertight triangle test, first two stages (misses by edge or by range, in float), net of set-up: {v - tri_setup} instructions")
    elif "probe_triangle_interval" in k:
        print(f"watertight triangle test, a deferred hit (edge signs, float range stage and its bounds), net of set-up: {v - tri_setup} instructions")
    elif "probe_triangle<(cwbvh::TriangleTest)0>" in k:
        print(f"watertight triangle test, whole (hit path, double fallbacks included), net of set-up: {v - tri_setup} instructions")
reference = next(v for k, v in net.items() if "probe_cwbvh_node<" in k and "false>" in k)
fast = next(v for k, v in net.items() if "probe_cwbvh_node<" in k and "true>" in k) - setup
kernel_shaped = next(v for k, v in net.items() if "probe_cwbvh_node_dispatch" in k) - reference
for k, v in net.items():
    if "probe_cwbvh_node<" in k:
        which = "fast (common path)" if "true>" in k else "reference arithmetic"
        print(f"node step, {which}, net of set-up: {v - setup} instructions")
    elif "probe_cwbvh_node_dispatch" in k:
        print(f"node step as the kernel compiles it (both tests present, chosen at run time), fast path "
              f"= total - reference: {v - reference} instructions")
if sys.argv[2] == "1" and kernel_shaped > fast + 16:
    print(f"FAIL: the kernel-shaped fast path ({kernel_shaped}) exceeds the fast probe ({fast}) by more than 16")
    sys.exit(1)
' "$tmp/probe.cubin" "$check"
