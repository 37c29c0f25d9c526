#!/usr/bin/env python3
"""Table of run.sh's output: per ray set, the warp rounds that run the watertight test's
double-precision path per ray without and with deferred hits, the refills that finish
deferred hits, and what deferral costs in node and triangle visits."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "../../../.."))
from bench.model_catalog_sets import read_runs  # noqa: E402

def parse(g, t):
    return {
        "rays": int(g(r"rays (\d+)")),
        "nodes": g(r"nodes/ray ([\d.]+)"),
        "tris": g(r"triangles/ray ([\d.]+)"),
        "rounds": g(r"in \d+ rounds \(([\d.]+) per ray"),
        "share": g(r"per ray, ([\d.]+)% of rounds"),
        "fin": g(r"refills \(([\d.]+) per ray\)") if "deferred hits" in t else 0.0,
        "deferred": g(r"deferred hits \d+ \(([\d.]+) per ray") if "deferred hits" in t else 0.0,
        "bad": int(g(r"check +(\d+) disagreements")),
        "ties": int(g(r"(\d+) ties")),
    }


order, rows = read_runs(sys.argv[1], parse)
print("| scene | view | rays | double-path rounds per ray (share of rounds): kernel before -> deferred | + refills finishing deferred hits per ray | deferred hits per ray | triangle tests per ray | node visits per ray | disagreements with the CPU reference (ties) |")
print("|---|---|---|---|---|---|---|---|---|")
sums = []
for key in order:
    r = rows[key]
    if "--no-defer-hits" not in r or "deferred" not in r:
        continue
    a, b = r["--no-defer-hits"], r["deferred"]
    print(f"| {key[0]} | {key[1]} | {key[2]} ({a['rays']}) | {a['rounds']:.3f} ({a['share']:.1f} %) -> {b['rounds']:.3f} ({b['share']:.1f} %) "
          f"| {b['fin']:.3f} | {b['deferred']:.2f} | {a['tris']:.2f} -> {b['tris']:.2f} | {a['nodes']:.2f} -> {b['nodes']:.2f} "
          f"| {a['bad']} ({a['ties']}) / {b['bad']} ({b['ties']}) |")
    sums.append((a["rounds"], b["rounds"] + b["fin"]))
if sums:
    before = sum(x for x, _ in sums) / len(sums)
    after = sum(y for _, y in sums) / len(sums)
    print(f"\nMean over {len(sums)} ray sets: {before:.3f} warp executions of the double path per ray before, "
          f"{after:.3f} with deferral (rounds + refills).")
