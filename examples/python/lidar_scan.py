"""A LiDAR-style scan (a spinning sensor: 64 channels from -25 to +15 degrees of elevation,
2048 steps of azimuth) from the eye of a catalog view, saved as a PNG: the range image and the
point cloud seen from above.

usage: PYTHONPATH=build/python /usr/bin/python3 examples/python/lidar_scan.py \
           [SCENE.glb|SCENE.cwbvh] [--view NAME] [-o lidar.png]
Default scene: ../shared/scenes/sponza_dabrovic.glb (y up; compiled next to the PNG on first use).
"""
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cwbvh  # noqa: E402
import example_args  # noqa: E402

args, path = example_args.parse("lidar.png")

# --- the user code: a sensor at the view's eye, one ray per channel and azimuth step ---
scene = cwbvh.open(path)
eye = np.array(cwbvh.view(scene, args.view)["eye"], np.float32)
elevation, azimuth = np.meshgrid(np.radians(np.linspace(15, -25, 64)), np.linspace(-np.pi, np.pi, 2048, endpoint=False),
                                 indexing="ij")
directions = np.stack([np.cos(elevation) * np.cos(azimuth), np.sin(elevation), np.cos(elevation) * np.sin(azimuth)],
                      axis=-1).reshape(-1, 3).astype(np.float32)
origins = np.broadcast_to(eye, directions.shape)  # a zero-stride view: packed once by trace
t, u, v, prim = scene.trace(origins, directions)
hit = prim != cwbvh.MISS
points = eye + t[hit, None] * directions[hit]

fig, (top, bottom) = plt.subplots(2, 1, figsize=(12, 9), gridspec_kw={"height_ratios": [1, 2.2]})
top.imshow(np.where(hit, t, np.nan).reshape(64, 2048), aspect="auto", cmap="turbo")
top.set_title("range image (64 channels x 2048 steps, %d%% returns)" % round(100 * hit.mean()))
top.axis("off")
bottom.scatter(points[:, 0], points[:, 2], c=points[:, 1], s=0.2, cmap="viridis")
bottom.plot(eye[0], eye[2], "r+", markersize=12)
bottom.set_aspect("equal")
bottom.set_title("%s: %d points from above (colour: height)" % (path.stem, len(points)))
fig.tight_layout()
fig.savefig(args.output, dpi=100)
print("wrote", args.output)
