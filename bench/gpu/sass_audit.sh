#!/usr/bin/env bash
# Per-kernel SASS audit of built CUDA code (issue 18): the instruction count of every
# kernel and the patterns that cost the kernels instructions before without showing in
# the step probes: local memory accesses (LDL/STL: per-ray state or the stack object in
# local memory), single-byte global loads (LDG.E.U8: a node read byte by byte), words
# rebuilt from bytes (LOP3 ... 0xff0000, R, 0xf8) and reads of the CTA's cluster slot
# (S2R SR_CgaCtaId: a shared address rebuilt in the loop). Expected today for the eight
# CWBVH kernels: LDL/STL only the stack's spill area (3-4 each), no LDG.E.U8, no byte
# rebuilds, one SR_CgaCtaId read each (bench/results/sass/2026-11-26-node-words).
# Needs cuobjdump (the GPU machine's CUDA 13.0 has it; this repository's build machine
# does not), or a text file that cuobjdump -sass wrote.
# usage: bench/gpu/sass_audit.sh FILE (.a / .o / .so / executable / cubin, or .sass text)
set -euo pipefail
in=${1:?usage: bench/gpu/sass_audit.sh FILE}
if [[ "$in" == *.sass || "$in" == *.txt ]]; then
  text=$(cat "$in")
else
  cuobjdump=${CUOBJDUMP:-$(command -v cuobjdump || echo /usr/local/cuda/bin/cuobjdump)}
  [ -x "$cuobjdump" ] || { echo "sass_audit: no cuobjdump (set CUOBJDUMP)"; exit 3; }
  text=$("$cuobjdump" -sass "$in")
fi
printf '%s\n' "$text" | python3 -c '
import re, subprocess, sys
rows, name, arch = [], None, ""
def new_row(n):
    return {"name": n, "arch": arch, "insts": 0, "ldl_stl": 0, "ldg_u8": 0, "rebuild": 0, "cga": 0}
for line in sys.stdin:
    m = re.search(r"arch = (sm_\d+)", line)
    if m: arch = m.group(1)
    m = re.search(r"Function : (\S+)", line)
    if m:
        rows.append(new_row(m.group(1))); continue
    if not rows or not re.search(r"/\*[0-9a-f]{4}\*/", line): continue
    r = rows[-1]
    r["insts"] += 1
    if re.search(r"\b(LDL|STL)\b", line): r["ldl_stl"] += 1
    if "LDG.E.U8" in line: r["ldg_u8"] += 1
    if re.search(r"0xff0000, R\d+, 0xf8", line): r["rebuild"] += 1
    if "SR_CgaCtaId" in line: r["cga"] += 1
names = subprocess.run(["c++filt"], input="\n".join(r["name"] for r in rows), capture_output=True, text=True).stdout.split("\n")
print("%-78s %-6s %5s %7s %6s %7s %8s" % ("kernel", "arch", "SASS", "LDL/STL", "LDG.U8", "rebuild", "CgaCtaId"))
for r, d in zip(rows, names):
    d = re.sub(r"\(cwbvh::gpu::.*LaunchParams\)", "", d.replace("void ", "")).replace("cwbvh::gpu::", "").replace("cwbvh::TriangleTest", "test").replace("cwbvh::HitMode", "mode")
    print("%-78s %-6s %5d %7d %6d %7d %8d" % (d[:78], r["arch"], r["insts"], r["ldl_stl"], r["ldg_u8"], r["rebuild"], r["cga"]))
'
