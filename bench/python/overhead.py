"""Python overhead of Scene.trace against `cwbvh trace` on the same rays (issue 20: at most 5 %
at 1M rays). Interleaved: each round runs the tool once (its printed trace seconds: the
trace_cwbvh_cpu call alone, the ray file already read, the hits vector already allocated) and
Python once (wall time of the scene.trace call: argument checks, the hit array's allocation
and first touch, the trace, the result views), so both see the same machine load. Reports the
median of the per-round ratios Python / tool, for the zero-copy (N, 8) input and for
origins + directions (N, 3), which are packed once (the documented copy).

usage: PYTHONPATH=build/python /usr/bin/python3 bench/python/overhead.py [--scene sponza_dabrovic]
       [--view nave] [--size 1024] [--rounds 9] [--threads 1,2] [--out DIR]
"""

import argparse
import json
import os
import pathlib
import re
import shutil
import statistics
import subprocess
import tempfile
import time

import cwbvh

ROOT = pathlib.Path(__file__).resolve().parents[2]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="sponza_dabrovic")
    ap.add_argument("--view", default="nave")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--kinds", default="primary,diffuse")
    ap.add_argument("--bin", default=str(ROOT / "build" / "bin"))
    ap.add_argument("--out")
    args = ap.parse_args()
    work = pathlib.Path(tempfile.mkdtemp(prefix="cwbvh-overhead-", dir="/dev/shm"))
    src = ROOT.parent / "shared" / "scenes" / (args.scene + ".glb")
    path = work / (args.scene + ".cwbvh")
    cwbvh.compile(str(src), path)
    scene = cwbvh.open(path)
    report = {"scene": args.scene, "view": args.view, "rounds": args.rounds, "load_average_at_start": os.getloadavg(),
              "rows": []}
    for kind in args.kinds.split(","):
        rays = cwbvh.camera_rays(scene, view=args.view, width=args.size, height=args.size)
        if kind == "diffuse":
            rays, _ = cwbvh.diffuse_rays(scene, rays)
        rays_file = work / ("rays-" + kind)
        subprocess.run([args.bin + "/cwbvh", "rays", str(path), "--" + kind, "--view", args.view, "--width",
                        str(args.size), "--height", str(args.size), "-o", str(rays_file)], check=True,
                       capture_output=True)
        assert (cwbvh.read_rays(rays_file).view("u4") == rays.view("u4")).all()
        o, d = rays[:, 0:3], rays[:, 4:7]
        for threads in map(int, args.threads.split(",")):
            tool, packed, split, inner, inner_split = [], [], [], [], []
            for _ in range(args.rounds):
                p = subprocess.run([args.bin + "/cwbvh", "trace", str(path), "--rays", str(rays_file), "--threads",
                                    str(threads)], check=True, capture_output=True, text=True).stdout
                tool.append(float(re.search(r"^seconds\s+([0-9.]+)", p, re.M).group(1)))
                t0 = time.perf_counter()
                h = scene.trace(rays, threads=threads)
                packed.append(time.perf_counter() - t0)
                inner.append(h.stats["seconds"])
                t0 = time.perf_counter()
                h = scene.trace(o, d, threads=threads)
                split.append(time.perf_counter() - t0)
                inner_split.append(h.stats["seconds"])
            row = {"kind": kind, "rays": len(rays), "threads": threads,
                   "tool_s_median": statistics.median(tool), "python_s_median": statistics.median(packed),
                   "python_split_s_median": statistics.median(split),
                   "ratio_median_of_rounds": statistics.median(p / t for p, t in zip(packed, tool)),
                   "ratio_split_median_of_rounds": statistics.median(p / t for p, t in zip(split, tool)),
                   # What Python adds around the same traversal in the same call (immune to the load
                   # changing between the tool's run and Python's): wall time - trace_cwbvh_cpu's time.
                   "added_s_median": statistics.median(p - i for p, i in zip(packed, inner)),
                   "added_split_s_median": statistics.median(p - i for p, i in zip(split, inner_split)),
                   "tool_s": tool, "python_s": packed, "python_split_s": split, "python_inner_s": inner,
                   "python_split_inner_s": inner_split}
            report["rows"].append(row)
            print("%-8s %8d rays %dT  tool %.4f s | python (N,8) %.4f s ratio %.3f, added %.1f ms | (N,3) %.4f s "
                  "ratio %.3f, added %.1f ms" % (
                      kind, len(rays), threads, row["tool_s_median"], row["python_s_median"],
                      row["ratio_median_of_rounds"], 1e3 * row["added_s_median"], row["python_split_s_median"],
                      row["ratio_split_median_of_rounds"], 1e3 * row["added_split_s_median"]), flush=True)
    shutil.rmtree(work, ignore_errors=True)  # the compiled scene and ray files in /dev/shm
    report["load_average_at_end"] = os.getloadavg()
    print("load average (1, 5, 15 min): %s at the start, %s at the end" % (report["load_average_at_start"],
                                                                         report["load_average_at_end"]))
    if args.out:
        out = pathlib.Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "overhead.json").write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
