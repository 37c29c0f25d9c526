#!/usr/bin/env python3
"""Compile time against triangle count: cwbvhc (the whole offline compile) next to Embree 3's
rtcCommitScene at MEDIUM and HIGH quality on the same triangles, in one run (issue 11).

    python3 bench/compile_scaling.py [--build-dir build] [--out DIR] [--threads 2] [--repeats 3]
                                     [--scenes NAME|PATH ...]

For every scene (default: every .glb of ../shared/scenes plus the glmark2 bunny, smallest first):
  * cwbvhc SCENE --threads T --stats-json: per-phase seconds, total, peak RSS (median of
    --repeats runs; the output file is the product's, no extra sections, written to /dev/shm when
    there is one and removed before each run);
  * cwbvhc --keep-mesh once more, for Embree's input (VERT/INDX of the same cleaned triangles);
  * cwbvh_bench_embree_build FILE --quality medium|high --threads T (median of --repeats), whose
    timer covers scene + geometry setup + rtcCommitScene (device creation excluded).
Writes DIR/compile_scaling.csv, DIR/compile_scaling.md (table, ratios, slopes) and, when
matplotlib is importable, DIR/compile_scaling.png (log-log time against triangles).

Slope: the least-squares fit of log(seconds) against log(triangles) over the scenes (1.0 =
linear), and the time per million input triangles on the largest scenes (>= 1M triangles).
"""
import argparse
import csv
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def run_json(cmd):
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def output_dir():
    """Where compiled outputs go: /dev/shm when there is one (see main)."""
    return "/dev/shm" if os.path.isdir("/dev/shm") and os.access("/dev/shm", os.W_OK) else None


def default_scenes():
    shared = os.path.join(ROOT, "..", "shared", "scenes")
    scenes = []
    bunny = "/usr/share/glmark2/models/bunny.obj"
    if os.path.exists(bunny):
        scenes.append(bunny)
    if os.path.isdir(shared):
        scenes += sorted(os.path.join(shared, f) for f in os.listdir(shared) if f.endswith(".glb"))
    return scenes


def fit_slope(xs, ys):
    lx = [math.log(x) for x in xs]
    ly = [math.log(y) for y in ys]
    mx, my = statistics.mean(lx), statistics.mean(ly)
    den = sum((a - mx) ** 2 for a in lx)
    return sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / den if den > 0 else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--build-dir", default=os.path.join(ROOT, "build"))
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "compile", time.strftime("%Y-%m-%d")))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--scenes", nargs="*")
    args = ap.parse_args()

    cwbvhc = os.path.join(args.build_dir, "bin", "cwbvhc")
    embree = os.path.join(args.build_dir, "bin", "cwbvh_bench_embree_build")
    for tool in (cwbvhc, embree):
        if not os.access(tool, os.X_OK):
            sys.exit(f"compile_scaling: {tool} not found (build the full configuration first)")
    scenes = args.scenes or default_scenes()
    if not scenes:
        sys.exit("compile_scaling: no scenes (../shared/scenes missing and no --scenes)")
    os.makedirs(args.out, exist_ok=True)
    rows = []
    load_start = os.getloadavg()
    # Outputs on tmpfs when there is one, each removed before the next run: on
    # this VM's ext4 (mounted with discard) writing over an existing 44 MB file
    # added 0.02-0.13 s of freeing the old inode to the write phase, noise
    # that says nothing about the compiler (Embree's timer writes no file).
    with tempfile.TemporaryDirectory(dir=output_dir()) as tmp:
        out_file = os.path.join(tmp, "scene.cwbvh")
        mesh_file = os.path.join(tmp, "mesh.cwbvh")
        stats_file = os.path.join(tmp, "stats.json")
        for scene in scenes:
            name = os.path.basename(scene)
            totals, phases, peaks = [], [], []
            for _ in range(args.repeats):
                if os.path.exists(out_file):
                    os.remove(out_file)
                # --flatten: Embree builds over the flattened triangles (the --keep-mesh file
                # below); an instanced glTF would otherwise compile to a two-level file.
                subprocess.run([cwbvhc, scene, "-o", out_file, "--threads", str(args.threads), "--quiet",
                                "--stats-json", stats_file, "--flatten"], check=True)
                s = json.load(open(stats_file))
                totals.append(s["seconds"]["total"])
                phases.append(s["seconds"])
                peaks.append(s["peak_rss_bytes"])
            med = statistics.median(totals)
            ph = phases[totals.index(med)] if med in totals else phases[0]
            subprocess.run([cwbvhc, scene, "-o", mesh_file, "--threads", str(args.threads), "--quiet",
                            "--keep-mesh"], check=True)
            emb = {}
            for q in ("medium", "high"):
                j = run_json([embree, mesh_file, "--quality", q, "--threads", str(args.threads),
                              "--repeats", str(args.repeats)])
                emb[q] = j["seconds"]
            row = {"scene": name, "input_triangles": s["input_triangles"], "triangles": s["triangles"],
                   "cwbvhc_s": round(med, 4), "sbvh_s": round(ph.get("sbvh", 0.0), 4),
                   "embree_medium_s": round(emb["medium"], 4), "embree_high_s": round(emb["high"], 4),
                   "ratio_high": round(med / emb["high"], 3), "ratio_medium": round(med / emb["medium"], 3),
                   "peak_mib": round(statistics.median(peaks) / 2**20, 1)}
            for k in ("import", "collapse", "slots", "encode", "write"):
                row[k + "_s"] = round(ph.get(k, 0.0), 4)
            rows.append(row)
            print(json.dumps(row), flush=True)
    load_end = os.getloadavg()
    rows.sort(key=lambda r: r["input_triangles"])
    with open(os.path.join(args.out, "compile_scaling.csv"), "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)

    tris = [r["input_triangles"] for r in rows]
    md = ["# Compile time against triangle count", "",
          f"Command: `python3 bench/compile_scaling.py --threads {args.threads} --repeats {args.repeats}`, "
          f"{time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores, load average "
          f"{load_start[0]:.2f} at start / {load_end[0]:.2f} at end. Seconds are medians of {args.repeats} runs; "
          "cwbvhc = the whole compile (import, SBVH, collapse, slots, encode, write); Embree = scene + "
          "geometry setup + rtcCommitScene on the same cleaned triangles.", "",
          "| scene | input tris | cwbvhc s | of which SBVH s | Embree MEDIUM s | Embree HIGH s | cwbvhc / HIGH | peak MiB |",
          "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        md.append(f"| {r['scene']} | {r['input_triangles']:,} | {r['cwbvhc_s']:.3f} | {r['sbvh_s']:.3f} | "
                  f"{r['embree_medium_s']:.3f} | {r['embree_high_s']:.3f} | {r['ratio_high']:.2f}x | {r['peak_mib']:.0f} |")
    md.append("")
    md.append("Slope of log(seconds) against log(triangles), all scenes (1.0 = linear):")
    for key, label in (("cwbvhc_s", "cwbvhc"), ("embree_medium_s", "Embree MEDIUM"), ("embree_high_s", "Embree HIGH")):
        md.append(f"- {label}: {fit_slope(tris, [r[key] for r in rows]):.2f}")
    big = [r for r in rows if r["input_triangles"] >= 1_000_000]
    if big:
        md.append("")
        md.append("Seconds per million input triangles on the scenes of >= 1M triangles:")
        for key, label in (("cwbvhc_s", "cwbvhc"), ("embree_medium_s", "Embree MEDIUM"), ("embree_high_s", "Embree HIGH")):
            per = [r[key] / (r["input_triangles"] / 1e6) for r in big]
            md.append(f"- {label}: {min(per):.2f}-{max(per):.2f} s")
    open(os.path.join(args.out, "compile_scaling.md"), "w").write("\n".join(md) + "\n")
    print("\n".join(md))

    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("compile_scaling: matplotlib not importable: no plot", file=sys.stderr)
        return
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for key, label, style in (("cwbvhc_s", "cwbvhc (whole compile)", "o-"),
                              ("embree_medium_s", "Embree rtcCommitScene MEDIUM", "s--"),
                              ("embree_high_s", "Embree rtcCommitScene HIGH", "^--")):
        ax.plot(tris, [r[key] for r in rows], style, label=label, markersize=4)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("input triangles")
    ax.set_ylabel(f"seconds ({args.threads} threads)")
    ax.set_title("Compile time against triangle count (same triangles, same run)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(args.out, "compile_scaling.png"), dpi=110)


if __name__ == "__main__":
    main()
