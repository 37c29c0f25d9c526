"""The benchmark's Embree peer (bench/python/embree_peer.py) agrees with cwbvh on the bunny, and
a ray mask of 0 hits nothing in Debian's Embree (the cause of Open3D 0.16's empty cast_rays)."""

import ctypes
import sys

import numpy as np
import pytest

import cwbvh
from conftest import SOURCE_DIR

sys.path.insert(0, str(SOURCE_DIR / "bench" / "python"))


@pytest.fixture
def embree_peer():
    try:
        ctypes.CDLL("libembree3.so.3")
    except OSError:
        pytest.skip("libembree3.so.3 not installed")
    import embree_peer
    return embree_peer


def test_embree_peer_agrees(bunny, embree_peer):
    rays = cwbvh.camera_rays(bunny, width=256, height=256)
    diffuse, _ = cwbvh.diffuse_rays(bunny, rays)
    scene = embree_peer.EmbreeScene(bunny.vertices(), bunny.indices())
    for r in (rays, diffuse):
        h = bunny.trace(r)
        for threads in (1, 2):
            t, u, v, prim = scene.intersect(r, threads=threads)
            assert (prim == h.prim).mean() > 0.999
            same = (prim == h.prim) & h.hit
            assert np.allclose(t[same], h.t[same], rtol=1e-4)
    if scene.ray_mask_supported:
        assert np.all(scene.intersect(rays, mask=0)[3] == embree_peer.MISS)
    scene.close()
