"""Python's hits are `cwbvh trace`'s to the bit (same rays, same file), closest and any hit,
primary and diffuse rays, on the bunny and a shared scene; Python's rays are `cwbvh rays`'s."""

import numpy as np
import pytest

import cwbvh
from conftest import run, tool


def tool_hits(path, rays_file, tmp_path, any_hit=False):
    hits_file = tmp_path / ("hits-any" if any_hit else "hits")
    run(tool("cwbvh"), "trace", path, "--rays", rays_file, "--hits", hits_file, *(["--any"] if any_hit else []))
    records, _ = cwbvh.read_hits(hits_file)
    return records.view(np.uint32)


def tool_rays(path, tmp_path, kind, view=None, size=192):
    out = tmp_path / ("rays-%s" % kind)
    args = [tool("cwbvh"), "rays", path, "--" + kind, "--width", size, "--height", size, "-o", out]
    if view:
        args += ["--view", view]
    run(*args)
    return out


@pytest.mark.parametrize("scene_fixture", ["bunny_file", "shared_file"])
@pytest.mark.parametrize("kind", ["primary", "diffuse"])
def test_hits_bit_identical_to_cwbvh_trace(request, tmp_path, scene_fixture, kind):
    path = request.getfixturevalue(scene_fixture)
    rays_file = tool_rays(path, tmp_path, kind)
    with cwbvh.open(path) as scene:
        rays = cwbvh.read_rays(rays_file)
        for any_hit in (False, True):
            expected = tool_hits(path, rays_file, tmp_path, any_hit)
            got = scene.trace(rays, any_hit=any_hit)
            assert got.stats["zero_copy"]
            assert np.array_equal(got.records.view(np.uint32), expected)
            if not any_hit:
                assert 0 < got.hit.sum() <= len(rays)
            # origins + directions (packed once) give the same bits
            split = scene.trace(rays[:, 0:3], rays[:, 4:7])
            if not any_hit:
                assert np.array_equal(split.records.view(np.uint32), expected)


@pytest.mark.parametrize("scene_fixture", ["bunny_file", "shared_file"])
def test_python_rays_bit_identical_to_cwbvh_rays(request, tmp_path, scene_fixture):
    path = request.getfixturevalue(scene_fixture)
    with cwbvh.open(path) as scene:
        views = cwbvh.views(scene)
        view = views[-1]["name"]
        primary = cwbvh.camera_rays(scene, view=view, width=192, height=192)
        assert np.array_equal(primary.view(np.uint32),
                              cwbvh.read_rays(tool_rays(path, tmp_path, "primary", view)).view(np.uint32))
        diffuse, paths = cwbvh.diffuse_rays(scene, primary)
        assert np.array_equal(diffuse.view(np.uint32),
                              cwbvh.read_rays(tool_rays(path, tmp_path, "diffuse", view)).view(np.uint32))
        assert paths.dtype == np.uint32 and len(paths) == len(diffuse)
        assert np.all(scene.trace(primary).prim[paths] != cwbvh.MISS)
