"""Ray helpers: camera rays from a view of the catalog (views/catalog.txt, the views every
benchmark uses), the paper's diffuse bounce rays, ray/hit files and packing into the ray-file
layout. All return float32 arrays of shape (N, 8): origin, tmin, direction, tmax per row, which
Scene.trace takes without a copy. The rays are those `cwbvh rays` writes, to the bit."""

import numpy as np

from . import _cwbvh
from ._paths import fspath


def pack_rays(origins, directions, tmin=0.0, tmax=np.inf):
    """(N, 8) float32 rays from origins and directions (N, 3); tmin/tmax scalars or (N,)."""
    origins = np.asarray(origins, dtype=np.float32)
    directions = np.asarray(directions, dtype=np.float32)
    if origins.ndim != 2 or origins.shape[1] != 3 or directions.shape != origins.shape:
        raise ValueError("pack_rays: origins and directions must both have shape (N, 3), got %s and %s"
                         % (origins.shape, directions.shape))
    rays = np.empty((origins.shape[0], 8), dtype=np.float32)
    rays[:, 0:3] = origins
    rays[:, 3] = tmin
    rays[:, 4:7] = directions
    rays[:, 7] = tmax
    return rays


def read_rays(path):
    """A ray file (spec/rays.md) as (N, 8) float32."""
    return _cwbvh.read_rays(fspath(path))


def read_hits(path, instances=False):
    """A hit file as (records (N, 4) float32: t, u, v, prim bits; flags). A version 1.1 file
    (`cwbvh trace --hits` on a two-level file) carries instances and is refused unless
    instances=True, which returns (records, instances (N,) uint32 or None for a 1.0 file, flags)."""
    if instances:
        return _cwbvh.read_hits(fspath(path), True)
    return _cwbvh.read_hits(fspath(path))


def views(scene, catalog=None, key=None):
    """The catalog's views of `scene` (a Scene): dicts with name, eye, target, fov, camera; one
    "default" view for a scene not in the catalog. `key`: the scene's catalog key (default: the
    file's stem); `catalog`: a catalog path (default: $CWBVH_VIEWS or views/catalog.txt)."""
    return scene._handle().views(key or _cwbvh.scene_key(scene.path), fspath(catalog, "catalog") if catalog else "")


def view(scene, which=None, catalog=None, key=None):
    """One view of `scene` (a dict as views() gives): `which` is a name or 1-based index; None:
    the first (the default camera for a scene not in the catalog)."""
    return _view(scene, which, catalog, key)


def _view(scene, which, catalog, key):
    return scene._handle().view(key or _cwbvh.scene_key(scene.path), "" if which is None else str(which),
                                fspath(catalog, "catalog") if catalog else "")


def camera_rays(scene, view=None, width=1024, height=1024, camera=None, catalog=None, key=None):
    """width x height pinhole rays, row 0 at the top, row-major, as `cwbvh rays --primary`:
    `view` is a catalog view name or 1-based index (default: the scene's first view, or the
    default camera for a scene not in the catalog); `camera` ("ex,ey,ez,tx,ty,tz,fov" or seven
    numbers) sets one by hand instead."""
    handle = scene._handle()
    if camera is not None and view is not None:
        raise ValueError("camera_rays: give view or camera, not both")
    if camera is None:
        camera = _view(scene, view, catalog, key)["camera"]
    return handle.camera_rays(camera, int(width), int(height))


def diffuse_rays(scene, primary, bounce=1, seed=1, threads=None):
    """The paper's diffuse rays of bounce `bounce` from `primary` (N, 8), as `cwbvh rays
    --diffuse`: (rays (M, 8), path index (M,) uint32 of each ray's primary ray)."""
    return scene._handle().diffuse_rays(primary, int(bounce), int(seed), 0 if threads is None else int(threads))
