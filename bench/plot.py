#!/usr/bin/env python3
"""PNG plots and Markdown tables from a bench/run.py results folder.

    python3 bench/plot.py DIR        (reads DIR/results.json, writes DIR/*.png and DIR/tables.md)
"""
import json
import os
import sys

plt = None  # matplotlib.pyplot, imported by make_all (tables need no matplotlib)


def _load(d):
    with open(os.path.join(d, "results.json")) as f:
        return json.load(f)


def _scenes(rows):
    out = []
    for r in rows:
        if r["scene"] not in out:
            out.append(r["scene"])
    return out


def _save(fig, d, name):
    fig.tight_layout()
    fig.savefig(os.path.join(d, name), dpi=90)
    plt.close(fig)


def plot_error(d, res):
    rows = res["error"]
    scenes = _scenes(rows)
    if not scenes:
        return
    n = len(scenes)
    cols = min(n, 3)
    nrows = (n + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(5.2 * cols, 4.0 * nrows), squeeze=False)
    for i, sc in enumerate(scenes):
        ax = axes[i // cols][i % cols]
        agg = {}
        for r in rows:
            if r["scene"] != sc:
                continue
            a = agg.setdefault(r["config"], {"count": 0, "wrong": 0, "seconds": 0.0})
            a["count"] += r["count"]
            a["wrong"] += r["false_miss"] + r["false_hit"] + r["wrong_prim"] + r["t_error"]
            a["seconds"] += r["seconds"]
        floor = 0.5 / max(a["count"] for a in agg.values())
        for k, (cfg, a) in enumerate(agg.items()):
            rate = a["wrong"] / a["count"]
            us = a["seconds"] / a["count"] * 1e6
            ax.scatter([us], [max(rate, floor)], marker="o" if rate > 0 else "v", s=40, color="C%d" % k,
                       label="%s (%d/%d)" % (cfg, a["wrong"], a["count"]))
        ax.set_yscale("log")
        ax.axhline(floor, color="grey", lw=0.5, ls=":")
        ax.set_xlabel("CPU time per ray, 1 thread [us] (primary + diffuse)")
        ax.set_ylabel("mismatch rate vs exact oracle")
        ax.set_title("%s (triangle marker on the dotted line: 0 errors)" % sc, fontsize=8)
        ax.legend(fontsize=6)
    for j in range(n, nrows * cols):
        axes[j // cols][j % cols].axis("off")
    _save(fig, d, "error_vs_time.png")


def _bar_groups(ax, labels, series, log=False, ylabel=""):
    w = 0.8 / max(1, len(series))
    for k, (name, vals) in enumerate(series):
        xs = [i + (k - (len(series) - 1) / 2) * w for i in range(len(labels))]
        ax.bar(xs, vals, w, label=name)
    ax.set_xticks(range(len(labels)))
    ax.set_xticklabels(labels, rotation=30, ha="right", fontsize=8)
    if log:
        ax.set_yscale("log")
    ax.set_ylabel(ylabel)
    ax.legend(fontsize=7)


def plot_build(d, res):
    b, e = res["build"], res["embree_build"]
    scenes = _scenes(b)
    if not scenes:
        return

    def ours(sc, builder, collapse, th):
        for r in b:
            if (r["scene"], r["builder"], r["collapse"], r["threads"]) == (sc, builder, collapse, th):
                return r["s_total"]
        return float("nan")

    def emb(sc, q, th):
        for r in e:
            if (r["scene"], r["quality"], r["threads"]) == (sc, q, th):
                return r["seconds"]
        return float("nan")

    series = [("cwbvhc sbvh/optimal 1t", [ours(s, "sbvh", "optimal", 1) for s in scenes]),
              ("cwbvhc sbvh/optimal 2t", [ours(s, "sbvh", "optimal", 2) for s in scenes]),
              ("cwbvhc embree/optimal 2t", [ours(s, "embree", "optimal", 2) for s in scenes]),
              ("Embree commit MEDIUM 2t", [emb(s, "medium", 2) for s in scenes]),
              ("Embree commit HIGH 2t", [emb(s, "high", 2) for s in scenes])]
    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(scenes) + 3), 4.2))
    _bar_groups(ax, scenes, series, log=True, ylabel="seconds (median)")
    ax.set_title("Build time: cwbvhc (whole offline compile incl. import and write) vs Embree rtcCommitScene", fontsize=9)
    _save(fig, d, "build_time.png")


def plot_traffic(d, res):
    t = res["traffic"]
    scenes = _scenes(t)
    if not scenes:
        return

    def get(sc, rays, tree, key):
        for r in t:
            if (r["scene"], r["rays"], r["mode"], r["tree"]) == (sc, rays, "closest", tree):
                return r[key]
        return float("nan")

    fig, axes = plt.subplots(1, 2, figsize=(max(9, 1.6 * len(scenes) + 4), 4.2))
    for ax, rays in zip(axes, ("primary", "diffuse")):
        series = [("CWBVH nodes", [get(s, rays, "cwbvh", "node_bytes_per_ray") for s in scenes]),
                  ("CWBVH triangles", [get(s, rays, "cwbvh", "tri_bytes_per_ray") for s in scenes]),
                  ("BVH2 nodes", [get(s, rays, "bvh2", "node_bytes_per_ray") for s in scenes]),
                  ("BVH2 triangles", [get(s, rays, "bvh2", "tri_bytes_per_ray") for s in scenes])]
        _bar_groups(ax, scenes, series, ylabel="bytes fetched per ray (closest hit)")
        ratios = [get(s, rays, "cwbvh", "bytes_per_ray") / get(s, rays, "bvh2", "bytes_per_ray") for s in scenes]
        ax.set_title("%s rays; CWBVH/BVH2 total: %s" % (rays, " ".join("%.2f" % r for r in ratios)), fontsize=8)
    _save(fig, d, "traffic_bytes_per_ray.png")


def plot_memory(d, res):
    rows = [r for r in res["trees"] if r.get("bvh2_bytes")]
    if not rows:
        return
    scenes = [r["scene"] for r in rows]
    fig, axes = plt.subplots(1, 2, figsize=(max(10, 2 * len(scenes) + 3), 4.2))
    _bar_groups(axes[0], scenes, [("CWBVH nodes (80 B)", [r["node_bytes_per_tri"] for r in rows]),
                                   ("BVH2 nodes (64 B)", [r["bvh2_bytes_per_tri"] for r in rows]),
                                   ("triangle records (40 B, shared)", [r["tris_bytes_per_tri"] for r in rows])],
                ylabel="bytes per input triangle")
    axes[0].set_title("Node memory, same SBVH; CWBVH/BVH2: %s" %
                      " ".join("%.2f" % r["node_bytes_ratio_cwbvh_over_bvh2"] for r in rows), fontsize=8)
    trees = res["trees"]
    configs = []
    for r in trees:
        if r["config"] not in configs and not r["config"].startswith("main"):
            configs.append(r["config"])
    series = []
    for c in configs:
        series.append((c, [next((r["avg_children"] for r in trees if r["scene"] == s and r["config"] == c),
                                float("nan")) for s in scenes]))
    _bar_groups(axes[1], scenes, series, ylabel="average children per wide node")
    axes[1].set_ylim(0, 8.5)
    axes[1].axhline(7.51, color="grey", ls=":", lw=0.8)
    axes[1].set_title("avg children per node (dotted: 7.51, the paper)", fontsize=8)
    _save(fig, d, "memory_and_children.png")


def plot_load(d, res):
    rows = res["load"]
    scenes = _scenes(rows)
    if not scenes:
        return

    def get(sc, v):
        return next((r["seconds"] for r in rows if r["scene"] == sc and r["variant"] == v), float("nan"))

    fig, ax = plt.subplots(figsize=(max(6, 1.1 * len(scenes) + 3), 4.2))
    _bar_groups(ax, scenes, [(v, [get(s, v) for s in scenes]) for v in ("cwbvh", "embree_medium", "embree_high")],
                log=True, ylabel="process start to first ray [s] (median)")
    ax.set_title("Start-up: map .cwbvh vs import mesh + Embree build", fontsize=9)
    _save(fig, d, "load_time.png")


def plot_cpu(d, res):
    """Mrays/s per scene, CWBVH CPU reference traversal vs Embree rtcIntersect1 (bench/cpu)."""
    rows = [r for r in res.get("cpu_trace", []) if r["query"] == "closest"]
    if not rows:
        return
    scenes = _scenes(rows)
    fig, axes = plt.subplots(1, 2, figsize=(max(10, 2 * len(scenes) + 4), 4.2))
    for ax, rays in zip(axes, ("primary", "diffuse")):
        series = []
        for th in (1, 2):
            for eng in ("cwbvh", "embree"):
                series.append(("%s %dt" % ("CWBVH (CPU ref.)" if eng == "cwbvh" else "Embree", th),
                               [next((r[eng + "_mrays"] for r in rows if r["scene"] == s and r["rays"] == rays and
                                      r["threads"] == th), float("nan")) for s in scenes]))
        _bar_groups(ax, scenes, series, ylabel="Mrays/s (closest hit)")
        ax.set_title("%s rays" % rays, fontsize=9)
    _save(fig, d, "mrays_vs_embree.png")


def _md(headers, rows):
    out = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    for r in rows:
        out.append("| " + " | ".join(str(x) for x in r) + " |")
    return "\n".join(out) + "\n"


def tables(d, res):
    m = res["meta"]
    s = ["Run: %s, `%s`, git %s, %s (%s cores), load average %s at start / %s at end, %.0f s wall.\n" %
         (m["date"], m["command"], m["git_rev"], m["cpu_model"], m["cores"],
          "/".join("%.1f" % x for x in m["loadavg_start"]), "/".join("%.1f" % x for x in m["loadavg_end"]),
          m["wall_seconds"])]
    b, e = res["build"], res["embree_build"]
    rows = []
    for sc in _scenes(b):
        def o(builder, collapse, th):
            return next((r for r in b if (r["scene"], r["builder"], r["collapse"], r["threads"]) ==
                         (sc, builder, collapse, th)), None)

        def em(q, th):
            return next((r["seconds"] for r in e if (r["scene"], r["quality"], r["threads"]) == (sc, q, th)),
                        float("nan"))

        r1, r2 = o("sbvh", "optimal", 1), o("sbvh", "optimal", 2)
        rows.append([sc, r2["triangles"], "%.3f" % r1["s_total"], "%.3f" % r2["s_total"],
                     "%.3f" % r2.get("s_sbvh", float("nan")), "%.3f" % r2.get("s_collapse", float("nan")),
                     "%.3f" % o("sbvh", "greedy", 2)["s_total"], "%.3f" % o("embree", "optimal", 2)["s_total"],
                     "%.3f" % em("medium", 1), "%.3f" % em("medium", 2), "%.3f" % em("high", 2),
                     "%.1fx" % (r2["s_total"] / em("high", 2)), "%.0f" % r2["peak_rss_mb"]])
    s.append("\n### Build time (seconds, median)\n\n")
    s.append(_md(["scene", "triangles", "cwbvhc sbvh/opt 1t", "2t", "of it: SBVH", "collapse", "sbvh/greedy 2t",
                  "embree/opt 2t", "Embree MEDIUM 1t", "MEDIUM 2t", "HIGH 2t", "cwbvhc 2t / Embree HIGH 2t",
                  "cwbvhc peak MB"], rows))
    tr = res["trees"]
    rows = []
    for r in tr:
        rows.append([r["scene"], r["config"], r["references"], r["wide_nodes"], "%.2f" % r["avg_children"],
                     "%.2f" % r["sah_binary"], "%.2f" % r["sah_wide"], "%.1f" % r["node_bytes_per_tri"],
                     "%.1f" % r["tris_bytes_per_tri"],
                     "%.1f" % r["bvh2_bytes_per_tri"] if "bvh2_bytes_per_tri" in r else "",
                     "%.2f" % r["node_bytes_ratio_cwbvh_over_bvh2"] if "bvh2_bytes" in r else ""])
    s.append("\n### Trees (SAH by the spec's formula; bytes per stored triangle)\n\n")
    s.append(_md(["scene", "config", "references", "wide nodes", "avg children", "SAH binary", "SAH wide",
                  "NODE B/tri", "TRIS B/tri", "BVH2 B/tri", "NODE/BVH2"], rows))
    t = res["traffic"]
    rows = []
    for sc in _scenes(t):
        for rays in ("primary", "diffuse"):
            c = next(r for r in t if (r["scene"], r["rays"], r["mode"], r["tree"]) == (sc, rays, "closest", "cwbvh"))
            b2 = next(r for r in t if (r["scene"], r["rays"], r["mode"], r["tree"]) == (sc, rays, "closest", "bvh2"))
            rows.append([sc, rays, c["count"], "%.1f" % c["nodes_per_ray"], "%.1f" % c["triangles_per_ray"],
                         "%.0f" % c["bytes_per_ray"], "%.1f" % b2["nodes_per_ray"], "%.1f" % b2["triangles_per_ray"],
                         "%.0f" % b2["bytes_per_ray"], "%.2f" % (c["bytes_per_ray"] / b2["bytes_per_ray"]),
                         c["disagreements_cwbvh_vs_bvh2"]])
    s.append("\n### Traversal traffic per ray (closest hit; CWBVH 80 B/node, BVH2 64 B/node, 40 B/triangle)\n\n")
    s.append(_md(["scene", "rays", "count", "CWBVH nodes", "CWBVH tris", "CWBVH bytes", "BVH2 nodes", "BVH2 tris",
                  "BVH2 bytes", "bytes CWBVH/BVH2", "hit disagreements"], rows))
    ld = res["load"]
    rows = []
    for sc in _scenes(ld):
        g = {r["variant"]: r["seconds"] for r in ld if r["scene"] == sc}
        rows.append([sc, "%.4f" % g["cwbvh"], "%.4f" % g["embree_medium"], "%.4f" % g["embree_high"],
                     "%.0fx" % (g["embree_medium"] / g["cwbvh"]), "%.0fx" % (g["embree_high"] / g["cwbvh"])])
    s.append("\n### Start-up: process start to first ray (seconds, median, warm page cache)\n\n")
    s.append(_md(["scene", ".cwbvh (mmap+validate+trace)", "import + Embree MEDIUM", "import + Embree HIGH",
                  "MEDIUM / cwbvh", "HIGH / cwbvh"], rows))
    er = res["error"]
    rows = []
    for r in er:
        rows.append([r["scene"], r["config"], r["rays"], r["count"], r["skipped"], r["false_miss"], r["false_hit"],
                     r["wrong_prim"], r["t_error"], "%.1e" % r["max_rel_t_error"], "%.3f" % r["mrays_per_s"]])
    s.append("\n### Error vs the exact oracle (closest hit, 1 thread)\n\n")
    s.append(_md(["scene", "config", "rays", "count", "skipped (hit within tol of tmin/tmax)", "false miss",
                  "false hit", "wrong prim", "t error > tol", "max rel t error", "Mrays/s"], rows))
    meta_rows = [[r["scene"], r["primary_rays"], r["diffuse_rays"], r["rel_tol"], "%d/%d" %
                  (r["brute_check_disagreements"], r["brute_check_rays"])] for r in res["error_meta"]]
    s.append("\n" + _md(["scene", "primary rays", "diffuse rays", "relative t tolerance",
                         "accelerated oracle vs brute force (disagreements/rays)"], meta_rows))
    cpu = res.get("cpu_trace", [])
    if cpu:
        rows = [[r["scene"], r["rays"], r["count"], r["query"], r["threads"], "%.2f" % r["cwbvh_mrays"],
                 "%.2f" % r["embree_mrays"], "%.2f" % r["ratio"]] for r in cpu]
        s.append("\n### CPU throughput, CWBVH reference traversal vs Embree rtcIntersect1/rtcOccluded1 (bench/cpu)\n\n")
        s.append(_md(["scene", "rays", "count", "query", "threads", "CWBVH Mrays/s", "Embree Mrays/s",
                      "CWBVH/Embree"], rows))
    with open(os.path.join(d, "tables.md"), "w") as f:
        f.write("".join(s))


def make_all(d, tables_only=False):
    global plt
    res = _load(d)
    tables(d, res)
    if tables_only:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot

    plt = pyplot
    plot_error(d, res)
    plot_build(d, res)
    plot_traffic(d, res)
    plot_memory(d, res)
    plot_load(d, res)
    plot_cpu(d, res)


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if a != "--tables-only"]
    if len(args) != 1:
        sys.exit("usage: plot.py [--tables-only] RESULTS_DIR")
    make_all(args[0], tables_only="--tables-only" in sys.argv)
