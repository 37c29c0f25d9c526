"""Why Debian 12's python3-open3d 0.16.1 RaycastingScene.cast_rays returns no hits.

Runs, on one triangle and one ray straight through it:
 1. Open3D as installed: cast_rays, count_intersections, test_occlusions, compute_distance;
 2. Embree 3.13.5 (Debian's libembree3, the library Open3D links) through embree_peer.py:
    whether ray masks are compiled in, and the same ray with mask 0 and with all mask bits;
 3. Open3D again in a child process with open3d_mask_shim.so preloaded: first reporting the
    mask Open3D passes to rtcIntersect1M, then setting it to all ones.
Prints a Markdown report.  usage: /usr/bin/python3 bench/python/open3d_check.py
"""

import json
import os
import pathlib
import subprocess
import sys
import tempfile

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
RAY = np.array([[0.2, 0.2, -1, 0, 0, 1]], np.float32)

CHILD = r"""
import json, numpy as np, open3d as o3d
s = o3d.t.geometry.RaycastingScene()
s.add_triangles(o3d.core.Tensor(np.array(%s, np.float32)), o3d.core.Tensor(np.array([[0, 1, 2]], np.uint32)))
r = o3d.core.Tensor(np.array(%s, np.float32))
print(json.dumps({"version": o3d.__version__, "cast_rays_t_hit": float(s.cast_rays(r)["t_hit"].numpy()[0]),
                  "count_intersections": int(s.count_intersections(r).numpy()[0]),
                  "test_occlusions": bool(s.test_occlusions(r).numpy()[0]),
                  "compute_distance": float(s.compute_distance(o3d.core.Tensor(np.array([[0.2, 0.2, -1]], np.float32))).numpy()[0])}))
""" % (TRIANGLE.tolist(), RAY.tolist())


def open3d(env=None):
    p = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True, env=env, check=True)
    return json.loads(p.stdout.strip().splitlines()[-1]), [l for l in p.stderr.splitlines() if l.startswith("shim:")]


def main():
    sys.path.insert(0, str(HERE))
    from embree_peer import EmbreeScene
    plain, _ = open3d()
    e = EmbreeScene(TRIANGLE, np.array([[0, 1, 2]], np.uint32))
    rays8 = np.array([[0.2, 0.2, -1, 0, 0, 0, 1, np.inf]], np.float32)
    t_mask0 = float(e.intersect(rays8, mask=0)[0][0])
    t_mask1 = float(e.intersect(rays8, mask=0xFFFFFFFF)[0][0])
    with tempfile.TemporaryDirectory() as d:
        so = pathlib.Path(d) / "shim.so"
        subprocess.run(["cc", "-shared", "-fPIC", "-O2", str(HERE / "open3d_mask_shim.c"), "-o", str(so), "-ldl"],
                       check=True)
        seen, log = open3d(dict(os.environ, LD_PRELOAD=str(so), CWBVH_SHIM_FIX_MASK="0"))
        fixed, _ = open3d(dict(os.environ, LD_PRELOAD=str(so), CWBVH_SHIM_FIX_MASK="1"))
    print("| run | cast_rays t_hit | count_intersections | test_occlusions | compute_distance |")
    print("|---|---|---|---|---|")
    for name, r in (("Open3D %s as installed" % plain["version"], plain),
                    ("Open3D under the shim, mask untouched", seen),
                    ("Open3D under the shim, mask set to 0xFFFFFFFF", fixed)):
        print("| %s | %s | %d | %s | %s |" % (name, r["cast_rays_t_hit"], r["count_intersections"],
                                             r["test_occlusions"], r["compute_distance"]))
    print()
    print("Embree %s: ray masks compiled in (RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED): %s" % (
        "3.13.5", e.ray_mask_supported))
    print("Embree directly (embree_peer.py), the same ray: mask 0 -> t = %s; mask 0xFFFFFFFF -> t = %s" % (
        t_mask0, t_mask1))
    print("Shim log: %s" % "; ".join(log))


if __name__ == "__main__":
    main()
