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


def test_view_of_a_scene_outside_the_catalog(bunny):
    """views() lists one view, "default", for a scene the catalog does not list: view() takes it
    by index 1 and by name, as it takes a catalog scene's views (it refused index 1)."""
    key = "not_in_the_catalog"
    listed = cwbvh.views(bunny, key=key)
    assert [v["name"] for v in listed] == ["default"]
    for which in (None, 1, "1", "default", np.int64(1)):
        assert cwbvh.view(bunny, which, key=key) == listed[0]
    first = cwbvh.camera_rays(bunny, width=8, height=8, key=key)
    assert np.array_equal(cwbvh.camera_rays(bunny, view=1, width=8, height=8, key=key), first)
    for which, match in ((2, r"view 2 out of range: .*has no views in .*its one view is 1 default"),
                         ("front", r"no view 'front': .*has no views in .*its one view is 1 default")):
        with pytest.raises(ValueError, match=match):
            cwbvh.view(bunny, which, key=key)
    # A scene of the catalog: its views by index and name, and no "default" among them.
    catalog = cwbvh.views(bunny)
    assert cwbvh.view(bunny, 1) == catalog[0] == cwbvh.view(bunny, catalog[0]["name"])
    with pytest.raises(ValueError, match=r"view %d out of range: .*1 %s" % (len(catalog) + 1, catalog[0]["name"])):
        cwbvh.view(bunny, len(catalog) + 1)
    with pytest.raises(ValueError, match="no view 'default'"):
        cwbvh.view(bunny, "default")


def misuse(scene, rays, out):
    """(call, exception, message) for wrong arguments to every public function: each is answered
    by the package's own short message naming the function and the argument, never by
    pybind11's list of signatures or a silent conversion (2.5 -> 2, None -> NaN, '0' -> GPU 0)."""
    o, d = np.ascontiguousarray(rays[:, 0:3]), np.ascontiguousarray(rays[:, 4:7])
    return [
        # Yes/no arguments: Python's truthiness would read "no" and "false" as True.
        (lambda: cwbvh.open(scene.path, deep="no"), TypeError, r"open: deep must be True or False, got 'no'"),
        (lambda: cwbvh.open(scene.path, verify_checksums=None), TypeError, r"open: verify_checksums must be True"),
        (lambda: scene.trace(o, d, any_hit="false"), TypeError, r"trace: any_hit must be True or False"),
        (lambda: scene.trace(o, d, watertight=0), TypeError, r"trace: watertight must be True or False, got 0"),
        (lambda: cwbvh.read_hits(out, instances="yes"), TypeError, r"read_hits: instances must be True or False"),
        (lambda: cwbvh.compile(None, out), TypeError, "compile: inputs must be a path or a list of paths"),
        (lambda: cwbvh.compile(3, out), TypeError, "compile: inputs must be a path"),
        (lambda: cwbvh.compile("x.obj", out, threads="2"), TypeError, r"compile: threads must be None or an integer"),
        (lambda: cwbvh.compile("x.obj", out, threads=2.0), TypeError, r"compile: threads .* got 2\.0"),
        (lambda: cwbvh.compile("x.obj", out, threads=2**40), ValueError, r"compile: threads .*\[1, 4096\]"),
        (lambda: cwbvh.compile("x.obj", out, split_alpha="x"), TypeError,
         r"compile: split_alpha must be a number in \[0.0, 1.0\], got str"),
        (lambda: cwbvh.compile("x.obj", out, split_alpha=None), TypeError, "compile: split_alpha must be a number"),
        (lambda: cwbvh.compile("x.obj", out, keep_mesh="yes"), TypeError,
         "compile: keep_mesh must be True or False, got str"),
        (lambda: scene.trace(None), TypeError, "rays: expected a float32 array, got NoneType"),
        (lambda: scene.trace(o, d, tmin="a"), TypeError, "trace: tmin must be a number, got 'a'"),
        (lambda: scene.trace(o, d, tmax=[1, 2]), TypeError, "trace: tmax must be a number"),
        (lambda: scene.trace(rays, threads="2"), TypeError, r"trace: threads must be None or an integer in \[1, 1024\]"),
        (lambda: scene.trace(rays, threads=2.5), TypeError, "trace: threads"),
        (lambda: scene.trace(rays, threads=-1), ValueError, "trace: threads .* got -1"),
        (lambda: scene.to_device("0"), TypeError, "to_device: device must be None or an integer >= -1, got '0'"),
        (lambda: scene.to_device(0.5), TypeError, "to_device: device"),
        (lambda: scene.to_device(-2), ValueError, "to_device: device"),
        (lambda: cwbvh.camera_rays(scene, width="a"), TypeError, r"camera_rays: width must be an integer in \[1, 16384\]"),
        (lambda: cwbvh.camera_rays(scene, width=2.5), TypeError, r"camera_rays: width .* got 2\.5"),
        (lambda: cwbvh.camera_rays(scene, height=-1), ValueError, r"camera_rays: height .* got -1"),
        (lambda: cwbvh.camera_rays(scene, width=2**40), ValueError, "camera_rays: width"),
        (lambda: cwbvh.camera_rays(scene, width=None), TypeError, "camera_rays: width .* got None"),
        (lambda: cwbvh.camera_rays(scene, camera=3), TypeError, r"camera_rays: camera must be an array of shape \(7,\)"),
        (lambda: cwbvh.camera_rays(scene, camera=["a"] * 7), TypeError, "camera_rays: camera must be an array"),
        (lambda: cwbvh.camera_rays(scene, camera=[1, 2]), ValueError, r"camera_rays: camera must have shape \(7,\)"),
        (lambda: cwbvh.camera_rays(scene, camera="1,2"), ValueError, "camera_rays: camera: expected 7"),
        (lambda: cwbvh.camera_rays(scene, view=1.5), TypeError, "camera_rays: view must be a view name .* got 1.5"),
        (lambda: cwbvh.camera_rays(scene, view=True), TypeError, "camera_rays: view must be a view name"),
        (lambda: cwbvh.camera_rays(scene, view=0), ValueError, "camera_rays: view .* got 0"),
        (lambda: cwbvh.camera_rays(str(scene.path)), TypeError, "camera_rays: scene must be a cwbvh.Scene .* got str"),
        (lambda: cwbvh.camera_rays(scene, key=3), TypeError, "camera_rays: key must be a str or None, got 3"),
        (lambda: cwbvh.views(None), TypeError, "views: scene must be a cwbvh.Scene"),
        (lambda: cwbvh.views(scene, key=b"bunny"), TypeError, "views: key must be a str"),
        (lambda: cwbvh.views(scene, catalog=3), TypeError, "views: catalog must be a str"),
        (lambda: cwbvh.view(scene, -1), ValueError, "view: which must be .* got -1"),
        (lambda: cwbvh.view(scene, 2.0), TypeError, "view: which must be"),
        (lambda: cwbvh.diffuse_rays(scene, None), TypeError, r"diffuse_rays: primary must be an array of shape \(N, 8\)"),
        (lambda: cwbvh.diffuse_rays(scene, "a"), TypeError, "diffuse_rays: primary must be an array"),
        (lambda: cwbvh.diffuse_rays(scene, o), ValueError, r"diffuse_rays: primary must have shape \(N, 8\), got"),
        (lambda: cwbvh.diffuse_rays(scene, rays, bounce=-1), ValueError, r"diffuse_rays: bounce .*\[1, 64\]"),
        (lambda: cwbvh.diffuse_rays(scene, rays, bounce=1.5), TypeError, "diffuse_rays: bounce"),
        (lambda: cwbvh.diffuse_rays(scene, rays, bounce="1"), TypeError, "diffuse_rays: bounce"),
        (lambda: cwbvh.diffuse_rays(scene, rays, seed=-1), ValueError, "diffuse_rays: seed"),
        (lambda: cwbvh.diffuse_rays(scene, rays, seed=2**40), ValueError, "diffuse_rays: seed"),
        (lambda: cwbvh.diffuse_rays(scene, rays, seed=None), TypeError, "diffuse_rays: seed"),
        (lambda: cwbvh.diffuse_rays(scene, rays, threads=-1), ValueError, "diffuse_rays: threads"),
        (lambda: cwbvh.diffuse_rays(scene, rays, threads=2.5), TypeError, "diffuse_rays: threads"),
        (lambda: cwbvh.pack_rays(None, d), TypeError, r"pack_rays: origins must be an array of shape \(N, 3\)"),
        (lambda: cwbvh.pack_rays("a", "b"), TypeError, "pack_rays: origins must be an array"),
        (lambda: cwbvh.pack_rays(o, d[:, :2]), ValueError, r"pack_rays: directions must have shape \(N, 3\)"),
        (lambda: cwbvh.pack_rays(o, d[:3]), ValueError, r"pack_rays: origins and directions must both have shape"),
        (lambda: cwbvh.pack_rays(o, d, tmin=None), TypeError, "pack_rays: tmin must be a number, got None"),
        (lambda: cwbvh.pack_rays(o, d, tmin="a"), TypeError, "pack_rays: tmin must be a number"),
        (lambda: cwbvh.pack_rays(o, d, tmax=[1, 2]), ValueError, r"pack_rays: tmax must have shape \(%d,\)" % len(o)),
    ]


def test_wrong_arguments_get_short_messages(bunny, tmp_path):
    rays = cwbvh.camera_rays(bunny, width=4, height=4)
    for call, error, match in misuse(bunny, rays, tmp_path / "o.cwbvh"):
        with pytest.raises(error, match=match) as e:
            call()
        text = str(e.value)
        assert "incompatible function arguments" not in text and "Unable to cast" not in text, text
        assert "\n" not in text and len(text) < 200, text
    assert not (tmp_path / "o.cwbvh").exists()


def test_right_arguments_of_other_types_still_work(bunny):
    """What the checks must keep taking: numpy integers, integer-valued arrays for rays,
    per-ray tmin/tmax arrays, a camera as 7 numbers of any numeric type, 0-d arrays."""
    rays = cwbvh.camera_rays(bunny, width=np.int64(8), height=np.uint16(8))
    assert rays.shape == (64, 8)
    o, d = rays[:, 0:3], rays[:, 4:7]
    packed = cwbvh.pack_rays(o.astype(np.float64), d.tolist(), tmin=np.zeros(64), tmax=np.float32(5))
    assert packed.dtype == np.float32 and np.all(packed[:, 7] == 5)
    camera = [float(x) for x in cwbvh.view(bunny)["camera"].split(",")]
    assert np.array_equal(cwbvh.camera_rays(bunny, camera=np.array(camera), width=8, height=8), rays)
    assert len(bunny.trace(o, d, tmin=np.float64(0), tmax=np.array(1e30), threads=np.int32(2))) == 64
    two, path = cwbvh.diffuse_rays(bunny, rays.astype(np.float64), bounce=np.int8(1), seed=np.uint32(7), threads=1)
    assert two.shape[1] == 8 and len(path) == len(two)
