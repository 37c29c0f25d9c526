"""Depth image of a scene from a view of the catalog, saved as a PNG.

usage: PYTHONPATH=build/python /usr/bin/python3 examples/python/depth_image.py \
           [SCENE.glb|SCENE.cwbvh] [--view NAME] [-o depth.png]
Default scene: ../shared/scenes/sponza_dabrovic.glb (compiled next to the PNG on first use).
"""
import argparse
import pathlib

import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cwbvh  # noqa: E402

ap = argparse.ArgumentParser()
ap.add_argument("scene", nargs="?", default=str(pathlib.Path(__file__).resolve().parents[3] / "shared/scenes/sponza_dabrovic.glb"))
ap.add_argument("--view", default=None)
ap.add_argument("-o", "--output", default="depth.png")
args = ap.parse_args()
path = pathlib.Path(args.scene)
if path.suffix != ".cwbvh":  # compile a mesh once, next to the output
    path = pathlib.Path(args.output).with_name(path.stem + ".cwbvh")
    path.exists() or cwbvh.compile(args.scene, path)

# --- the user code: open, make camera rays, trace, save ---
scene = cwbvh.open(path)
width, height = 800, 600
rays = cwbvh.camera_rays(scene, view=args.view, width=width, height=height)
t, u, v, prim = scene.trace(rays)
depth = np.where(prim != cwbvh.MISS, t, np.nan).reshape(height, width)
plt.figure(figsize=(8, 6))
plt.imshow(depth, cmap="viridis_r")
plt.colorbar(label="distance along the ray")
plt.title("%s: %d rays, %.0f%% hit" % (path.stem, len(t), 100 * (prim != cwbvh.MISS).mean()))
plt.axis("off")
plt.savefig(args.output, dpi=100, bbox_inches="tight")
print("wrote", args.output)
