#!/usr/bin/env python3
"""The table of README.md from run.sh's output: per catalog set, the worst ray with the fast
node test and with the reference test (node visits, triangle tests), and the fast test's mean
triangle tests and node visits over the reference's. usage: summarize.py result.txt"""
import re
import sys

LINE = re.compile(r"(\S+) (\S+) (\S+) (\S+) :: nodes/ray [\d.]+ worst ray \d+: (\d+) nodes, (\d+) triangles "
                  r".*mean ([\d.]+), ([\d.]+)")
rows = {}
for line in open(sys.argv[1]):
    m = LINE.match(line)
    if m:
        scene, view, kind, variant, wn, wt, mn, mt = m.groups()
        rows.setdefault((scene, view, kind), {})[variant] = (int(wn), int(wt), float(mn), float(mt))
print("| scene | view | rays | worst ray, fast test: nodes, triangles | reference test | mean triangles, fast / reference | mean nodes, fast / reference |")
print("|---|---|---|---|---|---|---|")
for (scene, view, kind), d in rows.items():
    if "fast" in d and "ref" in d:
        f, r = d["fast"], d["ref"]
        print(f"| {scene} | {view} | {kind} | {f[0]}, {f[1]} | {r[0]}, {r[1]} | {f[3] / r[3]:.3f} | {f[2] / r[2]:.3f} |")
