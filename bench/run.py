#!/usr/bin/env python3
"""The one benchmark driver: build, traffic, load and error benchmarks on a list of
scenes, then CSV/JSON results and PNG plots in one folder.

    python3 bench/run.py [--quick] [--scenes NAME|PATH ...] [--out DIR] [--build-dir DIR]

Builds nothing: expects the binaries in BUILD/bin (default: build/, then build-bench/).
Every timing is the median of --repeats runs (single-scene figures are ratios against
a peer measured in the same run). No timing is asserted anywhere.

Rays of the traffic, error and CPU-throughput benchmarks: the scene's first view in the
view catalog (--views, else $CWBVH_VIEWS, else views/catalog.txt), passed as --camera;
the default camera only for a scene not in the catalog.
"""
import argparse
import csv
import datetime
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SHARED = os.environ.get("CWBVH_SHARED_SCENES", os.path.join(os.path.dirname(ROOT), "shared", "scenes"))
BUNNY = "/usr/share/glmark2/models/bunny.obj"

# Default scene list: the bunny plus the shared scenes up to ~1M triangles, small to large.
DEFAULT_SCENES = [
    ("bunny", BUNNY),
    ("dragon_res4", "dragon_res4.obj"),
    ("sponza_dabrovic", "sponza_dabrovic.obj"),
    ("torcs_forza", "torcs_forza.glb"),
    ("fg_truman", "fg_truman.glb"),
    ("oa_dm5", "oa_dm5.glb"),
    ("oa_oacmpctf3", "oa_oacmpctf3.glb"),
    ("fg_cg57", "fg_cg57.glb"),
    ("dragon_res2", "dragon_res2.glb"),
    ("dragon", "dragon.glb"),
]
QUICK_SCENES = ["bunny", "dragon_res4"]
DEFAULT_VIEWS = os.environ.get("CWBVH_VIEWS") or os.path.join(ROOT, "views", "catalog.txt")

BUILD_CONFIGS = [("sbvh", "optimal"), ("sbvh", "greedy"), ("embree", "optimal"), ("embree", "greedy")]
DEFAULT_SPLIT_ALPHA = 3e-5  # cwbvhc --split-alpha default (SbvhConfig, compiler/include/cwbvh/compiler/build.h)


def log(*a):
    print("[bench]", *a, file=sys.stderr, flush=True)


def resolve_scene(item):
    for name, path in DEFAULT_SCENES:
        if item == name:
            p = path if os.path.isabs(path) else os.path.join(SHARED, path)
            return name, p
    if os.path.exists(item):
        return os.path.splitext(os.path.basename(item))[0], os.path.abspath(item)
    return item, None


def load_views(path):
    """The view catalog (spec/rays.md, "View catalog"): {scene: [(view, camera), ...]} in file
    order. The tools validate each camera when they get it; this checks the layout only."""
    with open(path) as f:
        lines = f.read().split("\n")
    if lines[0].split("#")[0].split() != ["cwbvh-views", "1"]:
        raise ValueError("%s:1: expected the header 'cwbvh-views 1'" % path)
    views = {}
    for n, line in enumerate(lines[1:], 2):
        fields = line.split("#")[0].split()
        if not fields:
            continue
        if len(fields) != 3:
            raise ValueError("%s:%d: expected 3 fields 'SCENE VIEW ex,ey,ez,tx,ty,tz,fov', got %d" %
                             (path, n, len(fields)))
        if any(v == fields[1] for v, _ in views.get(fields[0], [])):
            raise ValueError("%s:%d: duplicate view '%s' of scene '%s'" % (path, n, fields[1], fields[0]))
        views.setdefault(fields[0], []).append((fields[1], fields[2]))
    return views


def run(cmd, capture=True):
    r = subprocess.run(cmd, stdout=subprocess.PIPE if capture else None, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        raise RuntimeError("command failed (%d): %s\n%s" % (r.returncode, " ".join(cmd), r.stderr[-2000:]))
    return r.stdout


def run_json(cmd):
    return json.loads(run(cmd))


def median(xs):
    return statistics.median(xs) if xs else float("nan")


def loadavg():
    try:
        return os.getloadavg()
    except OSError:
        return (float("nan"),) * 3


def write_csv(path, rows):
    if not rows:
        return
    keys = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow(r)


class Bench:
    def __init__(self, args):
        self.args = args
        self.bin = os.path.join(args.build_dir, "bin")
        self.cwbvhc = os.path.join(self.bin, "cwbvhc")
        self.tools = {k: os.path.join(self.bin, "cwbvh_bench_" + k) for k in ("embree_build", "traffic", "startup", "error")}
        for p in [self.cwbvhc] + list(self.tools.values()):
            if not os.access(p, os.X_OK):
                sys.exit("run.py: %s not found: build first (cmake --build %s)" % (p, args.build_dir))
        self.views = load_views(args.views)
        self.work = tempfile.mkdtemp(prefix="cwbvh-bench-")
        self.failed = []  # scenes whose probe compile failed
        self.rows = {k: [] for k in ("build", "embree_build", "trees", "traffic", "load", "error", "error_meta", "cpu_trace")}

    # ---- 1. build -------------------------------------------------------------------------
    def compile(self, mesh, out, builder, collapse, threads, extra=()):
        stats = out + ".stats.json"
        # --flatten: the peers (Embree, tinybvh) build one flat tree over the world-space
        # triangles; an instanced glTF would otherwise give a two-level file (format 1.2).
        run([self.cwbvhc, mesh, "-o", out, "--builder", builder, "--collapse", collapse, "--threads", str(threads),
             "--stats-json", stats, "--quiet", "--flatten"] + list(extra))
        with open(stats) as f:
            return json.load(f)

    def bench_build(self, name, mesh, tris_hint):
        a = self.args
        reps = a.repeats if tris_hint < 400000 else max(1, min(a.repeats, 2))
        files = {}
        for builder, collapse in BUILD_CONFIGS:
            for threads in (1, 2):
                out = os.path.join(self.work, "%s_%s_%s.cwbvh" % (name, builder, collapse))
                runs = [self.compile(mesh, out, builder, collapse, threads) for _ in range(reps)]
                s0 = runs[0]
                row = {"scene": name, "builder": builder, "collapse": collapse, "split_alpha": DEFAULT_SPLIT_ALPHA,
                       "threads": threads, "repeats": reps, "triangles": s0["triangles"]}
                for phase in s0["seconds"]:
                    row["s_" + phase] = median([r["seconds"][phase] for r in runs])
                row["peak_rss_mb"] = median([r["peak_rss_bytes"] for r in runs]) / 2**20
                self.rows["build"].append(row)
                files[(builder, collapse)] = out
                log("%s build %s/%s threads=%d: %.3f s" % (name, builder, collapse, threads, row["s_total"]))
        # No spatial splits (alpha = 1), for the error study.
        out = os.path.join(self.work, "%s_sbvh_alpha1.cwbvh" % name)
        self.compile(mesh, out, "sbvh", "optimal", 2, ["--split-alpha", "1"])
        files["alpha1"] = out
        # The reference file: default configuration with the BVH2 and mesh sections.
        main = os.path.join(self.work, "%s_main.cwbvh" % name)
        st = self.compile(mesh, main, "sbvh", "optimal", 2, ["--keep-sbvh", "--keep-mesh"])
        files["main"] = main
        # Tree statistics of every tree (deterministic: independent of threads).
        for key, path in [(k, v) for k, v in files.items() if k != "main"]:
            with open(path + ".stats.json") as f:
                s = json.load(f)
            builder, collapse = key if isinstance(key, tuple) else ("sbvh", "optimal")
            self.rows["trees"].append(self.tree_row(name, builder, collapse, DEFAULT_SPLIT_ALPHA if key != "alpha1" else 1.0, s, None))
        # BV2L (leaf ranges) since format 1.1; BVH2 from older compilers.
        bvh2_bytes = st["bytes"].get("BV2L", st["bytes"].get("BVH2"))
        self.rows["trees"].append(self.tree_row(name, "sbvh", "optimal", DEFAULT_SPLIT_ALPHA, st, bvh2_bytes))
        self.rows["trees"][-1]["config"] = "main(+BVH2)"
        return files

    @staticmethod
    def tree_row(name, builder, collapse, alpha, s, bvh2_bytes):
        t = s["triangles"]
        b = s["bytes"]
        row = {"scene": name, "config": "%s/%s%s" % (builder, collapse, "" if alpha < 1 else "/alpha=1"),
               "builder": builder, "collapse": collapse, "split_alpha": alpha, "triangles": t,
               "references": s["references"], "spatial_splits": s["spatial_splits"], "binary_nodes": s["binary_nodes"],
               "wide_nodes": s["wide_nodes"], "avg_children": s["avg_children"], "sah_binary": s["sah_binary"],
               "sah_wide": s["sah_wide"], "node_bytes": b.get("NODE", 0), "tris_bytes": b.get("TRIS", 0),
               "node_bytes_per_tri": b.get("NODE", 0) / t, "tris_bytes_per_tri": b.get("TRIS", 0) / t}
        if bvh2_bytes is not None:
            row["bvh2_bytes"] = bvh2_bytes
            row["bvh2_bytes_per_tri"] = bvh2_bytes / t
            row["node_bytes_ratio_cwbvh_over_bvh2"] = b.get("NODE", 0) / bvh2_bytes if bvh2_bytes else float("nan")
        return row

    def bench_embree_build(self, name, main, tris_hint):
        reps = self.args.repeats if tris_hint < 400000 else max(1, min(self.args.repeats, 2))
        for quality in ("medium", "high"):
            for threads in (1, 2):
                j = run_json([self.tools["embree_build"], main, "--quality", quality, "--threads", str(threads),
                              "--repeats", str(reps)])
                self.rows["embree_build"].append({"scene": name, "quality": quality, "threads": threads, "repeats": reps,
                                                  "triangles": j["triangles"], "seconds": j["seconds"],
                                                  "commit_seconds": j["commit_seconds"],
                                                  "peak_rss_mb": j["peak_rss_bytes"] / 2**20})
                log("%s embree %s threads=%d: %.3f s" % (name, quality, threads, j["seconds"]))

    def camera_args(self, name):
        """--camera of the scene's first catalog view; [] (default camera) for a scene not in it."""
        v = self.views.get(name)
        return ["--camera", v[0][1]] if v else []

    # ---- 2. traffic -------------------------------------------------------------------------
    def bench_traffic(self, name, main):
        n = self.args.traffic_res
        j = run_json([self.tools["traffic"], main, "--width", str(n), "--height", str(n), "--bounces", "1",
                      "--threads", "2"] + self.camera_args(name))
        for r in j["rows"]:
            r = dict(r)
            r["scene"] = name
            r["disagreements_cwbvh_vs_bvh2"] = j["disagreements"]["%s_%s" % (r["rays"], r["mode"])]
            self.rows["traffic"].append(r)
        log("%s traffic done" % name)

    # ---- 3. load ----------------------------------------------------------------------------
    def bench_load(self, name, mesh, main):
        reps = str(self.args.load_repeats)
        # The renderer's file: NODE/TRIS/BNDS only matter, but the file is the one the compiler wrote.
        variants = [("cwbvh", ["cwbvh", main]), ("embree_medium", ["embree", mesh, "medium"]),
                    ("embree_high", ["embree", mesh, "high"])]
        for label, child in variants:
            j = run_json([self.tools["startup"], "measure", "--repeats", reps, "--"] + child)
            self.rows["load"].append({"scene": name, "variant": label, "repeats": int(reps), "seconds": j["seconds"],
                                      "file_mb": os.path.getsize(main) / 2**20 if label == "cwbvh" else
                                      os.path.getsize(mesh) / 2**20})
            log("%s load %s: %.4f s" % (name, label, j["seconds"]))

    # ---- 4. error ---------------------------------------------------------------------------
    def bench_error(self, name, files):
        main = files["main"]
        cfgs = [("sbvh/optimal watertight", main, "cwbvh", "watertight"),
                ("sbvh/optimal fast-tri", main, "cwbvh", "fast"),
                ("sbvh/greedy watertight", files[("sbvh", "greedy")], "cwbvh", "watertight"),
                ("embree/optimal watertight", files[("embree", "optimal")], "cwbvh", "watertight"),
                ("embree/optimal fast-tri", files[("embree", "optimal")], "cwbvh", "fast"),
                ("sbvh alpha=1 watertight", files["alpha1"], "cwbvh", "watertight"),
                ("BVH2 watertight", main, "bvh2", "watertight"),
                ("BVH2 fast-tri", main, "bvh2", "fast")]
        cmd = [self.tools["error"], "--reference", main, "--width", str(self.args.error_res), "--height",
               str(self.args.error_res), "--repeats", str(self.args.repeats), "--brute-check", "50"] + \
            self.camera_args(name)
        for c in cfgs:
            cmd += ["--config", ",".join(c)]
        j = run_json(cmd)
        self.rows["error_meta"].append({"scene": name, "triangles": j["triangles"], "primary_rays": j["rays"]["primary"],
                                        "diffuse_rays": j["rays"]["diffuse"], "rel_tol": j["rel_tol"],
                                        "brute_check_rays": j["brute_check"]["rays"],
                                        "brute_check_disagreements": j["brute_check"]["disagreements"]})
        for r in j["rows"]:
            r = dict(r)
            r.pop("file", None)
            r["scene"] = name
            wrong = r["false_miss"] + r["false_hit"] + r["wrong_prim"] + r["t_error"]
            r["error_rate"] = wrong / r["count"] if r["count"] else 0.0
            self.rows["error"].append(r)
        log("%s error done (brute-force check: %d disagreements of %d)" %
            (name, j["brute_check"]["disagreements"], j["brute_check"]["rays"]))

    # ---- CPU throughput vs Embree: bench/cpu's cwbvh_bench_cpu, when built ----------------------
    def bench_cpu(self, name, main):
        exe = os.path.join(self.bin, "cwbvh_bench_cpu")
        if not os.access(exe, os.X_OK):
            return
        out = os.path.join(self.work, name + "_cpu.json")
        run([exe, main, "--size", str(self.args.cpu_size), "--repeats", str(self.args.repeats), "--threads-max", "2",
             "--json", out] + self.camera_args(name))
        with open(out) as f:
            j = json.load(f)
        for r in j["results"]:
            r = dict(r)
            r["scene"] = name
            self.rows["cpu_trace"].append(r)
        log("%s cpu trace vs Embree done" % name)

    def go(self, scenes):
        a = self.args
        t_start = time.time()
        meta = {"date": datetime.datetime.now().isoformat(timespec="seconds"), "command": " ".join(sys.argv),
                "cpu_model": cpu_model(), "cores": os.cpu_count(), "platform": platform.platform(),
                "git_rev": git_rev(), "loadavg_start": loadavg(), "scenes": {n: m for n, m in scenes},
                "repeats": a.repeats, "quick": a.quick, "view_catalog": a.views,
                "views": {n: ("%s %s" % self.views[n][0]) if n in self.views else "default camera"
                          for n, _ in scenes}}
        for name, mesh in scenes:
            t0 = time.time()
            log("%s: rays from %s" % (name, meta["views"][name]))
            tris_hint = 0
            try:
                s = self.compile(mesh, os.path.join(self.work, name + "_probe.cwbvh"), "sbvh", "optimal", 2)
                tris_hint = s["triangles"]
            except RuntimeError as e:
                # Measured scenes go on; the run fails at the end (main), so a broken compiler
                # cannot leave a benchmark (or the smoke test) passing on the scenes it could do.
                log("%s failed to compile: %s" % (name, e))
                self.failed.append(name)
                continue
            files = self.bench_build(name, mesh, tris_hint)
            self.bench_embree_build(name, files["main"], tris_hint)
            self.bench_traffic(name, files["main"])
            self.bench_load(name, mesh, files["main"])
            self.bench_error(name, files)
            self.bench_cpu(name, files["main"])
            for f in os.listdir(self.work):
                if f.startswith(name + "_"):
                    os.remove(os.path.join(self.work, f))
            log("%s: %.1f s" % (name, time.time() - t0))
        meta["loadavg_end"] = loadavg()
        meta["wall_seconds"] = time.time() - t_start
        os.makedirs(a.out, exist_ok=True)
        for k, rows in self.rows.items():
            write_csv(os.path.join(a.out, k + ".csv"), rows)
        with open(os.path.join(a.out, "results.json"), "w") as f:
            json.dump({"meta": meta, **self.rows}, f, indent=1)
        shutil.rmtree(self.work, ignore_errors=True)
        return meta


def cpu_model():
    try:
        out = subprocess.run(["lscpu"], stdout=subprocess.PIPE, text=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name:"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def git_rev():
    try:
        return subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], stdout=subprocess.PIPE,
                              stderr=subprocess.DEVNULL, text=True).stdout.strip()
    except OSError:
        return ""


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="bunny + dragon_res4, fewer rays and repeats")
    p.add_argument("--scenes", nargs="+", help="scene names (%s) or mesh paths" % ", ".join(n for n, _ in DEFAULT_SCENES))
    p.add_argument("--out", help="results folder (default bench/results/cpu/<date>)")
    p.add_argument("--build-dir", help="CMake build folder holding bin/ (default build/, then build-bench/)")
    p.add_argument("--repeats", type=int, help="repeats per timing (default 3, quick 2)")
    p.add_argument("--views", default=DEFAULT_VIEWS,
                   help="view catalog (default $CWBVH_VIEWS, else views/catalog.txt); the first view of a scene "
                        "is the camera of its traffic, error and CPU rays")
    p.add_argument("--no-plots", action="store_true")
    a = p.parse_args()
    if not a.build_dir:
        for d in ("build", "build-bench"):
            if os.access(os.path.join(ROOT, d, "bin", "cwbvhc"), os.X_OK):
                a.build_dir = os.path.join(ROOT, d)
                break
        else:
            sys.exit("run.py: no build/bin/cwbvhc: build first or pass --build-dir")
    a.out = a.out or os.path.join(ROOT, "bench", "results", "cpu", datetime.date.today().isoformat())
    a.repeats = a.repeats or (2 if a.quick else 3)
    a.traffic_res = 128 if a.quick else 256
    a.error_res = 64 if a.quick else 160
    a.load_repeats = 3 if a.quick else 5
    a.cpu_size = 128 if a.quick else 256
    names = a.scenes or (QUICK_SCENES if a.quick else [n for n, _ in DEFAULT_SCENES])
    scenes = []
    missing = []
    for item in names:
        n, m = resolve_scene(item)
        if m and os.path.exists(m):
            scenes.append((n, m))
        else:
            log("scene %s not found: skipped" % item)
            missing.append(item)
    if not scenes:
        sys.exit("run.py: no scenes")
    # A scene named on the command line, or any scene under CI (CI=true), must be there.
    if missing and (a.scenes or os.environ.get("CI") == "true"):
        sys.exit("run.py: scene(s) not found: %s" % ", ".join(missing))
    b = Bench(a)
    meta = b.go(scenes)
    plot_py = os.path.join(os.path.dirname(os.path.abspath(__file__)), "plot.py")
    done = False
    if not a.no_plots:
        # matplotlib may live only in the system interpreter (Debian python3-matplotlib).
        for py in dict.fromkeys([sys.executable, "/usr/bin/python3"]):
            if os.access(py, os.X_OK) and subprocess.run([py, "-c", "import matplotlib"], stderr=subprocess.DEVNULL).returncode == 0:
                done = subprocess.run([py, plot_py, a.out]).returncode == 0
                break
        if not done:
            log("matplotlib not available: tables only, no PNG plots")
    if not done:
        if subprocess.run([sys.executable, plot_py, "--tables-only", a.out]).returncode != 0:
            sys.exit("run.py: writing tables failed")
    log("done in %.1f s: %s" % (meta["wall_seconds"], a.out))
    if b.failed:
        sys.exit("run.py: %d scene(s) failed to compile: %s" % (len(b.failed), ", ".join(b.failed)))


if __name__ == "__main__":
    main()
