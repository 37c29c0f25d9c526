"""Scene.trace on the CPU: error cases (shape, dtype, closed scene), non-contiguous inputs, large
N, several Python threads at once (and the GIL released meanwhile), a Scene outliving its file."""

import os
import shutil
import threading

import numpy as np
import pytest

import cwbvh
from conftest import ticks_while


@pytest.fixture
def rays(bunny):
    return cwbvh.camera_rays(bunny, width=128, height=128)


def bits(hits):
    return hits.records.view(np.uint32)


def test_results_and_views(bunny, rays):
    h = bunny.trace(rays)
    t, u, v, prim = h
    assert t.dtype == np.float32 and prim.dtype == np.uint32 and len(h) == len(rays)
    assert np.shares_memory(t, h.records) and np.shares_memory(prim, h.records)
    hit = prim != cwbvh.MISS
    assert hit.any() and (~hit).any()
    assert np.all(np.isinf(t[~hit])) and np.all(u[~hit] == 0) and np.all(t[hit] > 0)
    assert np.all(prim[hit] < bunny.info["triangles"])
    assert np.all((u[hit] >= 0) & (v[hit] >= 0) & (u[hit] + v[hit] <= 1.0001))
    # the hit point lies on the stored triangle
    tri = bunny.vertices()[bunny.indices()[prim[hit]]]
    p_bary = (1 - u[hit] - v[hit])[:, None] * tri[:, 0] + u[hit][:, None] * tri[:, 1] + v[hit][:, None] * tri[:, 2]
    p_ray = rays[hit, 0:3] + t[hit][:, None] * rays[hit, 4:7]
    assert np.abs(p_bary - p_ray).max() < 1e-4


def test_tmin_tmax_and_any_hit(bunny, rays):
    o, d = rays[:, 0:3], rays[:, 4:7]
    full = bunny.trace(o, d)
    hit = full.hit
    tmax = float(np.median(full.t[hit]))
    clipped = bunny.trace(o, d, tmax=tmax)
    assert np.all(clipped.t[clipped.hit] <= tmax) and clipped.hit.sum() < hit.sum()
    occluded = bunny.trace(o, d, any_hit=True)
    assert np.array_equal(occluded.hit, hit)
    fast = bunny.trace(rays, watertight=False)
    assert abs(int(fast.hit.sum()) - int(hit.sum())) <= 2


@pytest.mark.parametrize("make", [
    lambda r: (np.asfortranarray(r), None),
    lambda r: (np.repeat(r, 2, axis=0)[::2], None),
    lambda r: (np.ascontiguousarray(r[:, 0:3]).T.copy().T, np.asfortranarray(r[:, 4:7])),
    lambda r: (np.hstack([r, r])[:, 8:16], None),
    lambda r: (r[:, 0:3], r[:, 4:7]),
], ids=["fortran", "row-step", "transposed", "column-slice", "split-views"])
def test_non_contiguous_inputs_give_the_same_bits(bunny, rays, make):
    expected = bits(bunny.trace(rays))
    o, d = make(rays)
    got = bunny.trace(o) if d is None else bunny.trace(o, d)
    assert not got.stats["zero_copy"]
    assert np.array_equal(bits(got), expected)


def test_large_n(bunny):
    base = cwbvh.camera_rays(bunny, width=1024, height=1024)
    rays = np.concatenate([base, base])  # 2M rays
    h = bunny.trace(rays)
    assert len(h) == 2 * 1024 * 1024 and h.stats["rays"] == len(rays)
    assert np.array_equal(bits(h)[: len(base)], bits(h)[len(base):])


def test_threads_param(bunny, rays):
    expected = bits(bunny.trace(rays))
    for threads in (1, 2, 3):
        assert np.array_equal(bits(bunny.trace(rays, threads=threads)), expected)


def test_several_threads_tracing_at_once(bunny, rays):
    expected = bits(bunny.trace(rays))
    results, errors = [None] * 6, []

    def work(i):
        try:
            results[i] = bits(bunny.trace(rays if i % 2 else rays.copy(), threads=1 + i % 2))
        except Exception as e:  # noqa: BLE001 - reported below
            errors.append(e)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(6)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    assert all(np.array_equal(r, expected) for r in results)


def test_gil_released_while_tracing(bunny):
    rays = cwbvh.camera_rays(bunny, width=1024, height=1024)
    seconds, during = ticks_while(lambda: bunny.trace(rays, threads=1))
    assert seconds > 0.05
    assert len(during) >= 5, "the ticker thread did not run while trace ran: GIL held?"


def test_errors(bunny, rays):
    with pytest.raises(TypeError, match="float32"):
        bunny.trace(rays.astype(np.float64))
    with pytest.raises(TypeError, match="float32"):
        bunny.trace(rays[:, 0:3].astype(np.float16), rays[:, 4:7])
    with pytest.raises(TypeError, match="float32"):
        bunny.trace([[0.0, 0, 0, 0, 0, 0, 1, 1]])
    with pytest.raises(ValueError, match=r"shape \(N, 8\)"):
        bunny.trace(rays[:, 0:7])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        bunny.trace(rays[:, 0:4], rays[:, 4:7])
    with pytest.raises(ValueError, match=r"shape \(N, 3\)"):
        bunny.trace(rays[:, 0:3], rays[:, 4:7].ravel())
    with pytest.raises(ValueError, match="differ in length"):
        bunny.trace(rays[:10, 0:3], rays[:11, 4:7])
    with pytest.raises(ValueError, match="carry their own tmin"):
        bunny.trace(rays, tmax=1.0)
    with pytest.raises(ValueError, match="tmin <= tmax"):
        bunny.trace(rays[:, 0:3], rays[:, 4:7], tmin=2.0, tmax=1.0)
    with pytest.raises(ValueError, match="threads"):
        bunny.trace(rays, threads=0)
    with pytest.raises(TypeError, match="directions"):
        bunny.trace(rays[:, 0:3], "not an array")


def test_empty_and_invalid_rays(bunny):
    assert len(bunny.trace(np.zeros((0, 8), np.float32))) == 0
    bad = np.zeros((3, 8), np.float32)
    bad[0, 4:7] = 0.0            # zero direction
    bad[1, 0] = np.nan           # NaN origin
    bad[2, 4:7] = (0, 0, 1)
    bad[2, 3], bad[2, 7] = 2.0, 1.0  # tmin > tmax
    h = bunny.trace(bad)
    assert np.all(h.prim == cwbvh.MISS) and h.stats["invalid_rays"] == 3


def test_closed_scene(bunny_file, rays):
    scene = cwbvh.open(bunny_file)
    verts = scene.vertices()
    scene.close()
    assert scene.closed
    for call in (lambda: scene.trace(rays), lambda: scene.info, lambda: scene.vertices(),
                 lambda: cwbvh.camera_rays(scene), lambda: scene.to_device()):
        with pytest.raises(ValueError, match="closed"):
            call()
    assert verts.sum() != 0  # views taken before close keep the mapping
    with pytest.raises(ValueError, match="read-only"):
        verts[0, 0] = 1


def test_scene_outlives_its_file(bunny_file, tmp_path, rays):
    path = tmp_path / "moved.cwbvh"
    shutil.copy(bunny_file, path)
    scene = cwbvh.open(path)
    expected = bits(scene.trace(rays))
    os.remove(path)
    with open(path, "wb") as f:  # another file at the same path changes nothing
        f.write(b"\0" * 4096)
    assert np.array_equal(bits(scene.trace(rays)), expected)
    assert scene.info["nodes"] > 0
    with pytest.raises(cwbvh.Error):
        cwbvh.open(path)
    scene.close()


def test_host_dlpack_input(bunny, rays):
    class Wrapped:  # a CPU tensor known only through DLPack
        def __init__(self, a):
            self.a = a

        def __dlpack__(self, stream=None):
            return self.a.__dlpack__()

        def __dlpack_device__(self):
            return self.a.__dlpack_device__()

    assert np.array_equal(bits(bunny.trace(Wrapped(rays))), bits(bunny.trace(rays)))
