"""Misuse from Python that a hostile-input audit found answered wrongly (2026-11-27): a NUL
byte cut a path short (another file was opened or written), bytes and None paths were
str()-ed ("b'...'", a file named "None"), out-of-range or float prim ids wrapped in
Scene.sources, and an unaligned float32 array was refused as "expected float32, got float32"."""
import numpy as np
import pytest

import cwbvh


def test_paths_are_converted_as_python_does(bunny_file, tmp_path):
    with cwbvh.open(str(bunny_file).encode()) as scene:  # bytes, as os.open takes them
        assert scene.info["triangles"] == 69666
    for bad, error in ((str(bunny_file) + "\x00junk", ValueError), (None, TypeError), (3, TypeError)):
        with pytest.raises(error):
            cwbvh.open(bad)
    with pytest.raises(ValueError, match="embedded null byte"):
        cwbvh.read_rays(str(tmp_path / "r.rays") + "\x00zz")
    with pytest.raises(TypeError, match="output"):
        cwbvh.compile(str(bunny_file), None)
    with pytest.raises(ValueError, match="embedded null byte"):
        cwbvh.compile(str(bunny_file), str(tmp_path / "o.cwbvh") + "\x00zz")
    assert not (tmp_path / "o.cwbvh").exists()


def test_sources_refuses_ids_that_are_not_ids(bunny_file):
    with cwbvh.open(bunny_file) as scene:
        for bad in ([2**32 + 5], [-1]):
            with pytest.raises(ValueError):
                scene.sources(bad)
        with pytest.raises(TypeError):
            scene.sources([1.9])
        rows = scene.sources(np.array([0, 2**32 - 1], dtype=np.int64))
        assert rows[1, 0] == cwbvh.MISS and rows[0, 0] == 0


def test_unaligned_float32_rays_are_traced(bunny_file):
    with cwbvh.open(bunny_file) as scene:
        rays = cwbvh.camera_rays(scene, width=16, height=16)
        raw = bytearray(rays.size * 4 + 2)
        odd = np.frombuffer(raw, np.float32, offset=2, count=rays.size).reshape(rays.shape)
        odd[:] = rays
        a, b = scene.trace(odd), scene.trace(rays)
        assert np.array_equal(np.asarray(a.records).view(np.uint32), np.asarray(b.records).view(np.uint32))
