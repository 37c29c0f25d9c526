"""cwbvh from Python against Embree 3 from Python (embree_peer.py: ctypes over Debian's
libembree3, as embreex does) and Open3D 0.16's RaycastingScene (open3d_peer.py, run with the
ray-mask shim), on the same rays: primary and diffuse bounce-1 rays from every catalog view of
each scene, 1 and 2 threads, CPU. Reports time to first ray (cwbvh.open of the compiled file vs
building Embree's / Open3D's BVH from the mesh in memory), rays per second (median of --repeat
runs, cwbvh and Embree interleaved), and the agreement of the hits.

usage: PYTHONPATH=build/python /usr/bin/python3 bench/python/bench_python.py --out DIR
       [--scenes bunny,sponza_dabrovic,dragon] [--size 1024] [--repeat 3] [--no-open3d]
Writes DIR/results.json, DIR/table.md and DIR/throughput.png.
"""

import argparse
import importlib.util
import json
import os
import pathlib
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import cwbvh

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from embree_peer import EmbreeScene  # noqa: E402

ROOT = HERE.parents[1]
SCENES = ROOT.parent / "shared" / "scenes"


def scene_source(name):
    for ext in (".glb", ".obj"):
        if (SCENES / (name + ext)).exists():
            return SCENES / (name + ext)
    if name == "bunny":
        return pathlib.Path("/usr/share/glmark2/models/bunny.obj")
    raise SystemExit("scene %s not found under %s" % (name, SCENES))


def median(xs):
    return statistics.median(xs)


def agreement(prim_a, t_a, prim_b, t_b):
    same = prim_a == prim_b
    both = same & (prim_a != cwbvh.MISS)
    rel = np.abs(t_a[both] - t_b[both]) / np.maximum(np.abs(t_a[both]), 1e-30)
    return {"same_prim": float(same.mean()),
            "same_hit_or_miss": float(((prim_a != cwbvh.MISS) == (prim_b != cwbvh.MISS)).mean()),
            "t_rel_diff_max_same_prim": float(rel.max()) if rel.size else 0.0}


def shim_path(work):
    so = work / "open3d_mask_shim.so"
    subprocess.run(["cc", "-shared", "-fPIC", "-O2", str(HERE / "open3d_mask_shim.c"), "-o", str(so), "-ldl"],
                   check=True)
    return so


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True)
    ap.add_argument("--scenes", default="bunny,sponza_dabrovic,dragon")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-open3d", action="store_true")
    args = ap.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    work = pathlib.Path(tempfile.mkdtemp(prefix="cwbvh-pybench-", dir="/dev/shm" if os.path.isdir("/dev/shm") else None))
    has_open3d = importlib.util.find_spec("open3d") is not None
    if not has_open3d and not args.no_open3d:
        print("open3d is not installed (Debian: python3-open3d): no Open3D columns", flush=True)
    shim = None if args.no_open3d or not has_open3d else shim_path(work)
    results = {"machine": "%s, %d cores" % (platform.processor() or platform.machine(), os.cpu_count()),
               "size": args.size, "repeat": args.repeat, "load_average_at_start": os.getloadavg(), "scenes": {}}
    for name in args.scenes.split(","):
        src = scene_source(name)
        path = work / (name + ".cwbvh")
        stats = cwbvh.compile(str(src), path, keep_mesh=True)
        sres = {"triangles": stats["triangles"], "first_ray": {}, "views": {}}
        one = np.array([[0, 0, 0, 0, 0, 0, 1, np.inf]], np.float32)
        firsts = []
        for _ in range(5):
            t0 = time.perf_counter()
            with cwbvh.open(path) as s:
                s.trace(one)
            firsts.append(time.perf_counter() - t0)
        sres["first_ray"]["cwbvh open"] = median(firsts)
        scene = cwbvh.open(path)
        vertices, indices = np.array(scene.vertices()), np.array(scene.indices())
        for threads in (1, 2):
            firsts = []
            for _ in range(3):
                t0 = time.perf_counter()
                e = EmbreeScene(vertices, indices, quality="medium", threads=threads)
                e.intersect(one)
                firsts.append(time.perf_counter() - t0)
                e.close()
            sres["first_ray"]["embree build (%d thread%s)" % (threads, "s" if threads > 1 else "")] = median(firsts)
        embree = EmbreeScene(vertices, indices, quality="medium")
        o3d_dir = work / ("o3d-" + name)
        o3d_dir.mkdir()
        np.savez(o3d_dir / "mesh.npz", vertices=vertices, indices=indices)
        ray_sets = {}
        for view in cwbvh.views(scene):
            primary = cwbvh.camera_rays(scene, view=view["name"], width=args.size, height=args.size)
            diffuse, _ = cwbvh.diffuse_rays(scene, primary)
            ray_sets[view["name"] + "/primary"] = primary
            ray_sets[view["name"] + "/diffuse"] = diffuse
        for key, rays in ray_sets.items():
            np.save(o3d_dir / ("rays_%s.npy" % key.replace("/", "__")), rays)
            row = {"rays": len(rays)}
            for threads in (1, 2):
                cw, em, em_rtc = [], [], []
                for _ in range(args.repeat):  # interleaved: cwbvh, Embree, cwbvh, ...
                    t0 = time.perf_counter()
                    h = scene.trace(rays, threads=threads)
                    cw.append(time.perf_counter() - t0)
                    t0 = time.perf_counter()
                    et, eu, ev, ep = embree.intersect(rays, threads=threads)
                    em.append(time.perf_counter() - t0)
                    em_rtc.append(embree.last_trace_seconds)
                row["cwbvh_mrays_%d" % threads] = len(rays) / median(cw) / 1e6
                row["embree_mrays_%d" % threads] = len(rays) / median(em) / 1e6
                row["embree_rtc_only_mrays_%d" % threads] = len(rays) / median(em_rtc) / 1e6
            row["agree_embree"] = agreement(h.prim, h.t, ep, et)
            row["hit_fraction"] = float(h.hit.mean())
            row["prim"] = h.prim.copy()
            sres["views"][key] = row
        embree.close()
        scene.close()
        if shim is not None:
            env = dict(os.environ, LD_PRELOAD=str(shim), CWBVH_SHIM_FIX_MASK="1")
            subprocess.run([sys.executable, str(HERE / "open3d_peer.py"), str(o3d_dir), "--repeat", str(args.repeat)],
                           check=True, env=env, stderr=subprocess.DEVNULL)
            o3d = json.loads((o3d_dir / "open3d.json").read_text())
            sres["first_ray"]["open3d build (all cores)"] = o3d["first_ray_s"]
            for key, row in sres["views"].items():
                k = key.replace("/", "__")
                for threads in (1, 2):
                    row["open3d_mrays_%d" % threads] = row["rays"] / median(o3d["traces"]["%s/%d" % (k, threads)]) / 1e6
                prim = np.load(o3d_dir / ("open3d_%s_1.npy" % k))
                row["agree_open3d_same_prim"] = float((prim == row["prim"]).mean())
        for row in sres["views"].values():
            del row["prim"]
        results["scenes"][name] = sres
        print(json.dumps({name: sres["first_ray"]}), flush=True)
    shutil.rmtree(work, ignore_errors=True)  # compiled scenes and rays in /dev/shm
    results["load_average_at_end"] = os.getloadavg()
    (out / "results.json").write_text(json.dumps(results, indent=1))
    write_table(results, out / "table.md", open3d=shim is not None)
    plot(results, out / "throughput.png")


def write_table(results, path, open3d):
    lines = ["Rays per second (Mrays/s, median of %d runs, CPU, %dx%d rays per view; diffuse: bounce 1 of "
             "the paths that hit). %s; load average (1, 5, 15 min) %s at the start, %s at the end" % (
                 results["repeat"], results["size"], results["size"], results["machine"],
                 "/".join("%.1f" % x for x in results["load_average_at_start"]),
                 "/".join("%.1f" % x for x in results["load_average_at_end"])), ""]
    head = ("| scene | view / rays | N | cwbvh 1T | Embree 1T (rtcIntersect1M alone) | %scwbvh 2T | Embree 2T "
            "(rtcIntersect1M alone) | %scwbvh/Embree 1T | 2T | same prim as Embree | max rel. t diff (same prim) |")
    head = head % (("Open3D 1T | ", "Open3D 2T | ") if open3d else ("", ""))
    lines += [head, "|" + "---|" * (head.count("|") - 1)]
    for name, s in results["scenes"].items():
        for key, r in s["views"].items():
            o1 = "%.2f | " % r["open3d_mrays_1"] if open3d else ""
            o2 = "%.2f | " % r["open3d_mrays_2"] if open3d else ""
            lines.append("| %s | %s | %d | %.2f | %.2f (%.2f) | %s%.2f | %.2f (%.2f) | %s%.2fx | %.2fx | %.5f%% | %.1e |" % (
                name, key, r["rays"], r["cwbvh_mrays_1"], r["embree_mrays_1"], r["embree_rtc_only_mrays_1"], o1,
                r["cwbvh_mrays_2"], r["embree_mrays_2"], r["embree_rtc_only_mrays_2"], o2,
                r["cwbvh_mrays_1"] / r["embree_mrays_1"], r["cwbvh_mrays_2"] / r["embree_mrays_2"],
                100 * r["agree_embree"]["same_prim"], r["agree_embree"]["t_rel_diff_max_same_prim"]))
    ratios = {t: [r["cwbvh_mrays_%d" % t] / r["embree_mrays_%d" % t]
                  for s in results["scenes"].values() for r in s["views"].values()] for t in (1, 2)}
    rtc = {t: [r["cwbvh_mrays_%d" % t] / r["embree_rtc_only_mrays_%d" % t]
               for s in results["scenes"].values() for r in s["views"].values()] for t in (1, 2)}
    gm = lambda xs: float(np.exp(np.mean(np.log(xs))))  # noqa: E731
    lines += ["", "Geometric mean cwbvh/Embree (the wrapper call; rtcIntersect1M alone): 1 thread %.2fx (%.2fx), "
              "2 threads %.2fx (%.2fx)" % (gm(ratios[1]), gm(rtc[1]), gm(ratios[2]), gm(rtc[2])), ""]
    lines += ["Time to first ray (seconds, median): cwbvh = cwbvh.open (mmap + validation + checksums) and one "
              "ray; Embree / Open3D = building their BVH from the mesh already in memory and one ray", "",
              "| scene | triangles | " + " | ".join(next(iter(results["scenes"].values()))["first_ray"]) + " |",
              "|---|---|" + "---|" * len(next(iter(results["scenes"].values()))["first_ray"])]
    for name, s in results["scenes"].items():
        lines.append("| %s | %d | " % (name, s["triangles"]) + " | ".join("%.4f" % v for v in s["first_ray"].values())
                     + " |")
    if open3d:
        lines += ["", "Open3D agreement (same prim as cwbvh, 1 thread): " + ", ".join(
            "%s %s %.4f%%" % (n, k, 100 * r["agree_open3d_same_prim"])
            for n, s in results["scenes"].items() for k, r in s["views"].items())]
    path.write_text("\n".join(lines) + "\n")


def plot(results, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels, series = [], {}
    for name, s in results["scenes"].items():
        for key, r in s["views"].items():
            labels.append("%s\n%s" % (name, key))
            for k, v in r.items():
                if (k.endswith("_mrays_1") or k.endswith("_mrays_2")) and "rtc_only" not in k:
                    series.setdefault(k, []).append(v)
    fig, ax = plt.subplots(figsize=(max(8, 1.1 * len(labels)), 4.5))
    keys = sorted(series)
    width = 0.8 / len(keys)
    for i, k in enumerate(keys):
        engine, _, t = k.split("_")
        ax.bar(np.arange(len(labels)) + i * width, series[k], width, label="%s, %s thread%s" % (
            engine, t, "s" if t != "1" else ""))
    ax.set_xticks(np.arange(len(labels)) + 0.4 - width / 2)
    ax.set_xticklabels(labels, fontsize=7)
    ax.set_ylabel("Mrays/s (CPU)")
    ax.set_title("Tracing from Python: cwbvh vs Embree 3 (ctypes) vs Open3D 0.16 (mask shim)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
