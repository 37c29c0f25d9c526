#!/usr/bin/env python3
"""Tree quality of the compiler on every scene: issue 3's per-scene report.

    python3 bench/quality.py [--build-dir DIR] [--out DIR] [--scenes PATH ...]

Default scenes: the Stanford bunny (glmark2-data), the Draco glTF of assimp-testmodels
(glTF2/draco/2CylinderEngine.gltf) and every .glb in ../shared/scenes (or $CWBVH_SHARED_SCENES).
Per scene, cwbvhc with 2 threads in three configurations: our SBVH + optimal (DP) collapse
(the default), our SBVH + greedy collapse, Embree rtcBuildBVH HIGH + optimal collapse (same
reference budget). Reports the spec's SAH (binary, and wide on the decoded boxes), children per
wide node, references per triangle, whole-file bytes per input triangle, compile seconds and
peak RSS. Only the compiler runs: no traversal, so this covers the multi-million-triangle scenes
that bench/run.py leaves out. Writes quality.csv and quality.md to --out.
"""
import argparse
import csv
import datetime
import glob
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
CONFIGS = [("sbvh", "optimal"), ("sbvh", "greedy"), ("embree", "optimal")]


def default_scenes():
    scenes = []
    bunny = "/usr/share/glmark2/models/bunny.obj"
    if os.path.exists(bunny):
        scenes.append(bunny)
    draco = "/usr/share/assimp/models/glTF2/draco/2CylinderEngine.gltf"
    if os.path.exists(draco):
        scenes.append(draco)
    shared = os.environ.get("CWBVH_SHARED_SCENES", os.path.join(ROOT, "..", "shared", "scenes"))
    scenes += sorted(glob.glob(os.path.join(shared, "*.glb")), key=os.path.getsize)
    return scenes


def compile_stats(cwbvhc, mesh, builder, collapse, work):
    out = os.path.join(work, "q.cwbvh")
    stats = os.path.join(work, "q.json")
    r = subprocess.run([cwbvhc, mesh, "-o", out, "--builder", builder, "--collapse", collapse, "--threads", "2",
                        "--stats-json", stats, "--quiet"], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("quality.py: cwbvhc failed on %s: %s" % (mesh, r.stderr.strip()))
    with open(stats) as f:
        return json.load(f)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    p.add_argument("--out", default=os.path.join(HERE, "results", "quality", datetime.date.today().isoformat()))
    p.add_argument("--scenes", nargs="+")
    a = p.parse_args()
    cwbvhc = os.path.join(a.build_dir, "bin", "cwbvhc")
    if not os.access(cwbvhc, os.X_OK):
        sys.exit("quality.py: %s not found: build first" % cwbvhc)
    scenes = a.scenes or default_scenes()
    os.makedirs(a.out, exist_ok=True)
    rows = []
    with tempfile.TemporaryDirectory(prefix="cwbvh-quality-") as work:
        for mesh in scenes:
            name = os.path.basename(mesh)
            s = {cfg: compile_stats(cwbvhc, mesh, cfg[0], cfg[1], work) for cfg in CONFIGS}
            d = s[("sbvh", "optimal")]
            g = s[("sbvh", "greedy")]
            e = s[("embree", "optimal")]
            row = {
                "scene": name, "input_triangles": d["input_triangles"], "triangles": d["triangles"],
                "refs_per_tri": d["references"] / d["triangles"],
                "sah_binary": d["sah_binary"], "sah_binary_embree": e["sah_binary"],
                "sah_wide_optimal": d["sah_wide"], "sah_wide_greedy": g["sah_wide"],
                "children_optimal": d["avg_children"], "children_greedy": g["avg_children"],
                "bytes_per_input_tri": d["file_bytes"] / d["input_triangles"],
                "seconds_2t": d["seconds"]["total"], "peak_rss_mib": d["peak_rss_bytes"] / 2**20,
            }
            rows.append(row)
            print("[quality] %s: SAH %.2f (Embree %.2f), wide %.2f/%.2f, children %.2f/%.2f, %.1f B/tri, %.2f s"
                  % (name, row["sah_binary"], row["sah_binary_embree"], row["sah_wide_optimal"],
                     row["sah_wide_greedy"], row["children_optimal"], row["children_greedy"],
                     row["bytes_per_input_tri"], row["seconds_2t"]), flush=True)
    with open(os.path.join(a.out, "quality.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    lines = ["| scene | input tris | refs/tri | SAH binary (ours / Embree HIGH) | SAH wide (DP / greedy) | "
             "children (DP / greedy) | file B/input tri | compile s (2t) | peak MiB |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append("| %s | %d | %.3f | %.2f / %.2f%s | %.2f / %.2f | %.2f / %.2f | %.1f | %.2f | %.0f |" % (
            r["scene"], r["input_triangles"], r["refs_per_tri"], r["sah_binary"], r["sah_binary_embree"],
            "" if r["sah_binary"] <= r["sah_binary_embree"] else " (higher)", r["sah_wide_optimal"],
            r["sah_wide_greedy"], r["children_optimal"], r["children_greedy"], r["bytes_per_input_tri"],
            r["seconds_2t"], r["peak_rss_mib"]))
    with open(os.path.join(a.out, "quality.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
