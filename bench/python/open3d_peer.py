"""Open3D 0.16's RaycastingScene on the benchmark's rays, in its own process (bench_python.py
starts it with open3d_mask_shim.so preloaded: without the shim Debian's Open3D returns no hits,
see open3d_check.py). Reads mesh.npz (vertices, indices) and rays_*.npy from a folder, writes
open3d.json (build + first-ray seconds, trace seconds per rays file and thread count) and the
hit prims as open3d_<name>_<threads>.npy.

usage: open3d_peer.py DIR --threads 1,2 --repeat R
"""

import argparse
import json
import pathlib
import time

import numpy as np
import open3d as o3d


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("dir")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    d = pathlib.Path(args.dir)
    mesh = np.load(d / "mesh.npz")
    vertices = o3d.core.Tensor(mesh["vertices"])
    indices = o3d.core.Tensor(mesh["indices"])
    one = o3d.core.Tensor(np.array([[0, 0, 0, 0, 0, 1]], np.float32))
    firsts = []
    for _ in range(3):
        t0 = time.perf_counter()
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(vertices, indices)
        scene.cast_rays(one)  # the BVH is built at the first query
        firsts.append(time.perf_counter() - t0)
    out = {"version": o3d.__version__, "first_ray_s": sorted(firsts)[1], "traces": {}}
    for path in sorted(d.glob("rays_*.npy")):
        rays = np.load(path)
        r6 = o3d.core.Tensor(np.ascontiguousarray(np.hstack([rays[:, 0:3], rays[:, 4:7]])))
        name = path.stem[len("rays_"):]
        for threads in map(int, args.threads.split(",")):
            secs = []
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                result = scene.cast_rays(r6, nthreads=threads)
                secs.append(time.perf_counter() - t0)
            prim = result["primitive_ids"].numpy().astype(np.uint32)
            np.save(d / ("open3d_%s_%d.npy" % (name, threads)), prim)
            out["traces"]["%s/%d" % (name, threads)] = secs
    (d / "open3d.json").write_text(json.dumps(out))


if __name__ == "__main__":
    main()
