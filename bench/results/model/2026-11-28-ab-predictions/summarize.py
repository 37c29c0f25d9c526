#!/usr/bin/env python3
"""Table of run.sh's output: per ray set, the warp model's node and triangle warp steps with
the kernel as it is, and each A/B variant's warp steps relative to it; then geometric means
over the ray sets, primary and diffuse separately."""
import math
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../.."))
from bench.model_catalog_sets import read_runs  # noqa: E402

VARIANTS = ["--no-defer-hits", "--reference-node-test", "--postpone-percent=10", "--postpone-percent=35",
            "--postpone-percent=50"]
def parse(g, text):
    return {
        "rays": int(g(r"rays (\d+)")),
        "nodes": g(r"nodes/ray ([\d.]+)"),
        "tris": g(r"triangles/ray ([\d.]+)"),
        "node_steps": g(r"node (\d+), triangle"),
        "tri_steps": g(r"triangle (\d+):"),
        "lanes_tri": g(r"lanes/tri step ([\d.]+)"),
        "double": g(r"in \d+ rounds \(([\d.]+) per ray"),
    }


order, rows = read_runs(sys.argv[1], parse)


def gm(v):
    return math.exp(sum(math.log(x) for x in v) / len(v)) if v else float("nan")


print("| scene | view | rays | kernel: node / triangle warp steps per 32 rays (lanes per triangle round) | "
      + " | ".join(f"{v.replace('=', ' ')}: node, triangle, all" for v in VARIANTS) + " |")
print("|---|---|---|---|" + "---|" * len(VARIANTS))
means = {}
for key in order:
    r = rows[key]
    d = r.get("default")
    if not d or d["rays"] == 0 or any(v not in r for v in VARIANTS):
        continue
    per32 = 32.0 / d["rays"]
    cells = []
    for v in VARIANTS:
        x = r[v]
        rn = x["node_steps"] / d["node_steps"] if d["node_steps"] else float("nan")
        rt = x["tri_steps"] / d["tri_steps"] if d["tri_steps"] else float("nan")
        ra = (x["node_steps"] + x["tri_steps"]) / (d["node_steps"] + d["tri_steps"])
        cells.append(f"{rn:.3f}, {rt:.3f}, {ra:.3f}")
        for name, val in (("node", rn), ("tri", rt), ("all", ra)):
            if val == val and val > 0:
                means.setdefault((key[2], v, name), []).append(val)
    print(f"| {key[0]} | {key[1]} | {key[2]} ({d['rays']}) | {d['node_steps'] * per32:.1f} / {d['tri_steps'] * per32:.1f} "
          f"({d['lanes_tri']:.1f}) | " + " | ".join(cells) + " |")
print()
print("Geometric means over the ray sets of the variant's warp steps over the kernel's (> 1: the variant takes more "
      "steps; steps, not time):")
print()
print("| rays | " + " | ".join(f"{v.replace('=', ' ')}: node, triangle, all" for v in VARIANTS) + " |")
print("|---|" + "---|" * len(VARIANTS))
for kind in ("primary", "diffuse"):
    cells = []
    for v in VARIANTS:
        cells.append(", ".join(f"{gm(means.get((kind, v, n), [])):.3f}" for n in ("node", "tri", "all")))
    print(f"| {kind} | " + " | ".join(cells) + " |")
dp = [(rows[k]["--no-defer-hits"]["double"], rows[k]["default"]["double"]) for k in order
      if "default" in rows[k] and "--no-defer-hits" in rows[k]]
if dp:
    print(f"\nDouble-path triangle rounds per ray, mean over {len(dp)} ray sets: without deferral "
          f"{sum(a for a, _ in dp) / len(dp):.3f}, with it {sum(b for _, b in dp) / len(dp):.3f} (refills that "
          "finish deferred hits not counted here).")

# An instruction estimate for the reference node test's A/B only (the one variant whose step
# cost differs): warp instructions = node steps x W_node + triangle steps x W_tri, with W_node
# 255 (the fast node step, 187 by step_sizes.sh, plus ~68 of loop control on its common path,
# bench/results/sass/2026-11-27-kernel-loop) or 441 (the reference arithmetic's 373 plus the same
# 68), and W_tri 140 (a triangle round: 104-162 for the float stages or a deferred hit, nine
# shared loads, the round's vote). Code sizes, not executed instructions.
W_FAST, W_REF, W_TRI = 255.0, 441.0, 140.0
est = {}
for key in order:
    r = rows[key]
    d, x = r.get("default"), r.get("--reference-node-test")
    if not d or not x or d["rays"] == 0:
        continue
    a = d["node_steps"] * W_FAST + d["tri_steps"] * W_TRI
    b = x["node_steps"] * W_REF + x["tri_steps"] * W_TRI
    est.setdefault(key[2], []).append(a / b)
for kind in ("primary", "diffuse"):
    if est.get(kind):
        v = est[kind]
        print(f"\nEstimated warp instructions, kernel over --reference-node-test, {kind}: geometric mean {gm(v):.3f} "
              f"over {len(v)} ray sets (range {min(v):.3f}-{max(v):.3f}; weights: node {W_FAST:.0f} fast / {W_REF:.0f} "
              f"reference, triangle round {W_TRI:.0f})")
