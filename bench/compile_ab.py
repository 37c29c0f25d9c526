#!/usr/bin/env python3
"""Before/after compile time of two cwbvhc builds next to Embree, in one run (issue 11).

    python3 bench/compile_ab.py --before OLD/bin/cwbvhc --after build/bin/cwbvhc \\
        [--embree build/bin/cwbvh_bench_embree_build] [--threads 2] [--runs 5] [--json OUT.json] SCENE...

Thread scaling of one build: the same binary on both sides with its own thread count,
    python3 bench/compile_ab.py --before build/bin/cwbvhc --before-threads 1 \\
        --after build/bin/cwbvhc --after-threads 2 --runs 5 dragon.glb
(--threads sets both sides and Embree; --before-threads / --after-threads override one side;
Embree runs with --threads, default the after side's count).

Per scene and round: `before`, `after` (alternating, so that drift of a shared machine hits both)
and Embree 3 rtcCommitScene at HIGH quality on the same cleaned triangles (the `after` build's
--keep-mesh output; the timer covers scene + geometry setup + commit). Outputs go to /dev/shm when
there is one and are removed before each run (overwriting a file on this VM's ext4 added up to
0.13 s of freeing the old inode to the write phase). Prints per scene the median and range of the
whole compile (`seconds.total` of --stats-json), the SBVH phase and the peak RSS, the after/before
and after/HIGH ratios (medians of the same rounds), before/after (the speed-up of the after side),
and the load average before and after. --json also writes every round's figures, the command line
and the load averages.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

from compile_scaling import output_dir, run_json


def compile_once(binary, scene, out, stats, threads):
    if os.path.exists(out):
        os.remove(out)
    subprocess.run([binary, scene, "-o", out, "--threads", str(threads), "--quiet", "--stats-json", stats],
                   check=True)
    with open(stats) as f:
        s = json.load(f)
    return s["seconds"]["total"], s["seconds"].get("sbvh", 0.0), s["peak_rss_bytes"] / 2**20


def embree_once(embree, mesh, threads):
    return run_json([embree, mesh, "--quality", "high", "--threads", str(threads), "--repeats", "1"])["seconds"]


def summary(xs):
    return f"{statistics.median(xs):.3f} ({min(xs):.3f}-{max(xs):.3f})"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--before", required=True)
    ap.add_argument("--after", required=True)
    ap.add_argument("--embree", default=None, help="cwbvh_bench_embree_build (default: next to --after)")
    ap.add_argument("--threads", type=int, default=None, help="both sides and Embree (default 2)")
    ap.add_argument("--before-threads", type=int, default=None, help="threads of the before side (default --threads)")
    ap.add_argument("--after-threads", type=int, default=None, help="threads of the after side (default --threads)")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--json", default=None, help="also write every round's figures here")
    ap.add_argument("scenes", nargs="+")
    a = ap.parse_args()
    threads = {"before": a.before_threads or a.threads or 2, "after": a.after_threads or a.threads or 2}
    embree_threads = a.threads or threads["after"]
    record = {"command": " ".join([os.path.basename(sys.argv[0])] + sys.argv[1:]), "before": a.before,
              "after": a.after, "threads": threads, "embree_threads": embree_threads, "runs": a.runs,
              "load_average_start": os.getloadavg(), "nproc": os.cpu_count(), "scenes": {}}
    embree = a.embree or os.path.join(os.path.dirname(a.after), "cwbvh_bench_embree_build")
    for tool in (a.before, a.after, embree):
        if not os.access(tool, os.X_OK):
            sys.exit(f"compile_ab: {tool} is not an executable")
    print(f"threads before {threads['before']}, after {threads['after']}, Embree {embree_threads}; "
          f"{a.runs} rounds, load average {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory(dir=output_dir()) as tmp:
        out, stats, mesh = (os.path.join(tmp, n) for n in ("out.cwbvh", "stats.json", "mesh.cwbvh"))
        for scene in a.scenes:
            subprocess.run([a.after, scene, "-o", mesh, "--threads", str(threads["after"]), "--quiet",
                            "--keep-mesh"], check=True)
            rows = {"before": [], "after": [], "high": []}
            for _ in range(a.runs):
                rows["before"].append(compile_once(a.before, scene, out, stats, threads["before"]))
                rows["after"].append(compile_once(a.after, scene, out, stats, threads["after"]))
                rows["high"].append(embree_once(embree, mesh, embree_threads))
            tb = [r[0] for r in rows["before"]]
            ta = [r[0] for r in rows["after"]]
            th = rows["high"]
            print(f"{os.path.basename(scene)}:")
            for k, t in (("before", tb), ("after", ta)):
                sb = [r[1] for r in rows[k]]
                pk = [r[2] for r in rows[k]]
                print(f"  {k:6s} total {summary(t)} s, sbvh {summary(sb)} s, peak {statistics.median(pk):.1f} MiB")
            print(f"  Embree HIGH {summary(th)} s")
            print(f"  after/before {statistics.median(ta) / statistics.median(tb):.3f}, "
                  f"after/HIGH {statistics.median(ta) / statistics.median(th):.2f} "
                  f"(per round {min(x / y for x, y in zip(ta, th)):.2f}-{max(x / y for x, y in zip(ta, th)):.2f}), "
                  f"before/HIGH {statistics.median(tb) / statistics.median(th):.2f}")
            speedup = [x / y for x, y in zip(tb, ta)]
            print(f"  before/after {statistics.median(tb) / statistics.median(ta):.3f} "
                  f"(per round {min(speedup):.3f}-{max(speedup):.3f})")
            record["scenes"][os.path.basename(scene)] = {
                k: [{"total_s": r[0], "sbvh_s": r[1], "peak_mib": r[2]} for r in rows[k]] for k in ("before", "after")}
            record["scenes"][os.path.basename(scene)]["embree_high_s"] = th
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    record["load_average_end"] = os.getloadavg()
    if a.json:
        with open(a.json, "w") as f:
            json.dump(record, f, indent=1)


if __name__ == "__main__":
    main()
