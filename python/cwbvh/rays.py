"""Ray helpers: camera rays from a view of the catalog (views/catalog.txt, the views every
benchmark uses), the paper's diffuse bounce rays, ray/hit files and packing into the ray-file
layout. All return float32 arrays of shape (N, 8): origin, tmin, direction, tmax per row, which
Scene.trace takes without a copy. The rays are those `cwbvh rays` writes, to the bit."""

import numpy as np

from . import _args, _cwbvh
from ._paths import fspath


def pack_rays(origins, directions, tmin=0.0, tmax=np.inf):
    """(N, 8) float32 rays from origins and directions (N, 3); tmin/tmax scalars or (N,)."""
    origins = _args.floats(origins, "pack_rays: origins", (None, 3))
    directions = _args.floats(directions, "pack_rays: directions", (None, 3))
    if directions.shape != origins.shape:
        raise ValueError("pack_rays: origins and directions must both have shape (N, 3), got %s and %s"
                         % (origins.shape, directions.shape))
    n = origins.shape[0]
    tmin, tmax = _per_ray(tmin, "pack_rays: tmin", n), _per_ray(tmax, "pack_rays: tmax", n)
    rays = np.empty((n, 8), dtype=np.float32)
    rays[:, 0:3] = origins
    rays[:, 3] = tmin
    rays[:, 4:7] = directions
    rays[:, 7] = tmax
    return rays


def _per_ray(value, where, n):
    """A number, or one per ray: (n,)."""
    return _args.number(value, where) if np.ndim(value) == 0 else _args.floats(value, where, (n,))


def read_rays(path):
    """A ray file (spec/rays.md) as (N, 8) float32."""
    return _cwbvh.read_rays(fspath(path, "read_rays: path"))


def read_hits(path, instances=False):
    """A hit file as (records (N, 4) float32: t, u, v, prim bits; flags). A version 1.1 file
    (`cwbvh trace --hits` on a two-level file) carries instances and is refused unless
    instances=True, which returns (records, instances (N,) uint32 or None for a 1.0 file, flags)."""
    if _args.flag(instances, "read_hits: instances"):
        return _cwbvh.read_hits(fspath(path, "read_hits: path"), True)
    return _cwbvh.read_hits(fspath(path, "read_hits: path"))


def views(scene, catalog=None, key=None):
    """The catalog's views of `scene` (a Scene): dicts with name, eye, target, fov, camera; one
    "default" view for a scene not in the catalog. `key`: the scene's catalog key (default: the
    file's stem); `catalog`: a catalog path (default: $CWBVH_VIEWS or views/catalog.txt)."""
    handle = _args.scene_handle(scene, "views: scene")
    return handle.views(_key(handle, key, "views"), _catalog(catalog, "views"))


def view(scene, which=None, catalog=None, key=None):
    """One view of `scene` (a dict as views() gives), picked among views(scene): `which` is a
    name or 1-based index; None: the first. A scene not in the catalog has the one view
    "default" (index 1), the default camera."""
    return _view(_args.scene_handle(scene, "view: scene"), which, catalog, key, "view", "which")


def _view(handle, which, catalog, key, where, arg):
    if which is None:
        which = ""
    elif not isinstance(which, str):
        which = str(_args.integer(which, "%s: %s" % (where, arg), 1,
                                  expected="a view name (str) or a 1-based index (int >= 1)"))
    return handle.view(_key(handle, key, where), which, _catalog(catalog, where))


def _key(handle, key, where):
    return _args.text(key, where + ": key", none="") or _cwbvh.scene_key(handle.path)


def _catalog(catalog, where):
    return fspath(catalog, where + ": catalog") if catalog is not None else ""


def camera_rays(scene, view=None, width=1024, height=1024, camera=None, catalog=None, key=None):
    """width x height pinhole rays, row 0 at the top, row-major, as `cwbvh rays --primary`:
    `view` is a catalog view name or 1-based index (default: the scene's first view, or the
    default camera for a scene not in the catalog); `camera` ("ex,ey,ez,tx,ty,tz,fov" or seven
    numbers) sets one by hand instead."""
    handle = _args.scene_handle(scene, "camera_rays: scene")
    width = _args.integer(width, "camera_rays: width", 1, 16384)
    height = _args.integer(height, "camera_rays: height", 1, 16384)
    if camera is not None and view is not None:
        raise ValueError("camera_rays: give view or camera, not both")
    if camera is None:
        camera = _view(handle, view, catalog, key, "camera_rays", "view")["camera"]
    elif not isinstance(camera, str):
        camera = _args.floats(camera, "camera_rays: camera", (7,)).tolist()
    return handle.camera_rays(camera, width, height)


def diffuse_rays(scene, primary, bounce=1, seed=1, threads=None):
    """The paper's diffuse rays of bounce `bounce` from `primary` (N, 8), as `cwbvh rays
    --diffuse`: (rays (M, 8), path index (M,) uint32 of each ray's primary ray)."""
    handle = _args.scene_handle(scene, "diffuse_rays: scene")
    primary = _args.floats(primary, "diffuse_rays: primary", (None, 8))
    bounce = _args.integer(bounce, "diffuse_rays: bounce", 1, 64)
    seed = _args.integer(seed, "diffuse_rays: seed", 0, 2**32 - 1)
    threads = _args.integer(threads, "diffuse_rays: threads", 1, 1024, none=0)
    return handle.diffuse_rays(primary, bounce, seed, threads)
