"""Depth image of a scene from a view of the catalog, saved as a PNG.

usage: PYTHONPATH=build/python /usr/bin/python3 examples/python/depth_image.py \
           [SCENE.glb|SCENE.cwbvh] [--view NAME] [-o depth.png]
Default scene: ../shared/scenes/sponza_dabrovic.glb (compiled next to the PNG on first use).
"""
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cwbvh  # noqa: E402
import example_args  # noqa: E402

args, path = example_args.parse("depth.png")

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
