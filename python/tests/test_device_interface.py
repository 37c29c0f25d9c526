"""The GPU path's interface handling, tested without a GPU: fake device arrays exposing
__cuda_array_interface__ or DLPack (over host memory), a stand-in for the Scene's device handle
that records what trace would hand the kernels, and the DeviceArray results (both interfaces).
The kernels themselves run only where there is a GPU (test_gpu_trace_matches_cpu)."""

import numpy as np
import pytest

import cwbvh
from cwbvh import _arrays, _cwbvh


class FakeCAI:
    """A "device" array over host memory: only __cuda_array_interface__."""

    def __init__(self, a, version=3, stream=None, strides=True, mask=None, typestr=None):
        self.a = a
        self.cai = {"shape": a.shape, "typestr": typestr or a.dtype.str, "data": (a.ctypes.data, False),
                    "version": version}
        if strides:
            self.cai["strides"] = a.strides
        if version >= 3:
            self.cai["stream"] = stream
        if mask is not None:
            self.cai["mask"] = mask

    @property
    def __cuda_array_interface__(self):
        return self.cai


class FakeDLPack:
    """A "CUDA" tensor over host memory, known only through DLPack; records the stream asked for."""

    def __init__(self, a, device=(2, 0)):
        self.a, self.device, self.streams = a, device, []

    def __dlpack_device__(self):
        return self.device

    def __dlpack__(self, stream=None):
        self.streams.append(stream)
        item = self.a.itemsize
        return _cwbvh.dlpack_capsule(self.a, self.a.ctypes.data, self.device[0], self.device[1], list(self.a.shape),
                                     [s // item for s in self.a.strides], 2 if self.a.dtype.kind == "f" else 1,
                                     8 * item)


class RecordingHandle:
    """Stands in for the module's scene handle on the device: records trace_device's arguments and
    returns a host buffer, so the Python side runs end to end."""

    def __init__(self, real, on_device=True):
        self.real, self.on_device, self.calls, self.device_id = real, on_device, [], 0
        self.buffers = []

    def __getattr__(self, name):
        return getattr(self.real, name)

    def trace_device(self, org, org_row, dir_, dir_row, n, tmin, tmax, stream, any_hit, watertight):
        self.calls.append(dict(org=org, org_row=org_row, dir=dir_, dir_row=dir_row, n=n, tmin=tmin, tmax=tmax,
                               stream=stream, any_hit=any_hit, watertight=watertight))
        return self.wrap(np.zeros((n, 4), np.float32))

    def wrap(self, buf):
        """buf as the module's device buffer (ptr, nbytes, device), kept for the test."""
        self.buffers.append(buf)

        class Buffer:
            ptr = buf.ctypes.data
            nbytes = buf.nbytes
            device = 0
            keep = buf
        return Buffer()


@pytest.fixture
def fake_scene(bunny_file):
    scene = cwbvh.open(bunny_file)
    scene._h = RecordingHandle(scene._h)
    yield scene
    scene._h.real.close()


@pytest.fixture
def rays(bunny_file):
    with cwbvh.open(bunny_file) as scene:
        return cwbvh.camera_rays(scene, width=16, height=16)


def test_cai_packed_rays_zero_copy(fake_scene, rays):
    hits = fake_scene.trace(FakeCAI(rays, stream=7), any_hit=True)
    call = fake_scene._h.calls[-1]
    assert call["org"] == rays.ctypes.data and call["org_row"] == 32 and call["dir"] == 0
    assert call["n"] == len(rays) and call["stream"] == 7 and call["any_hit"] and call["watertight"]
    # results: DeviceArrays over the one Hit buffer, on the stream the work went to
    assert isinstance(hits.t, _arrays.DeviceArray)
    buf = fake_scene._h.buffers[-1]
    for col, (arr, typestr) in enumerate(zip(hits, ["<f4", "<f4", "<f4", "<u4"])):
        cai = arr.__cuda_array_interface__
        assert cai["data"][0] == buf.ctypes.data + 4 * col and cai["shape"] == (len(rays),)
        assert cai["strides"] == (16,) and cai["typestr"] == typestr and cai["stream"] == 7 and cai["version"] == 3
    assert hits.records.__cuda_array_interface__["shape"] == (len(rays), 4)


def test_cai_versions_strides_and_streams(fake_scene, rays):
    o, d = np.ascontiguousarray(rays[:, 0:3]), rays[:, 4:7]  # d: rows 32 bytes apart
    fake_scene.trace(FakeCAI(o, version=2, strides=False), FakeCAI(d, version=2), tmin=0.5, tmax=9.0)
    call = fake_scene._h.calls[-1]
    assert call["org_row"] == 12 and call["dir_row"] == 32 and call["dir"] == d.ctypes.data
    assert (call["tmin"], call["tmax"]) == (0.5, 9.0)
    assert call["stream"] == _arrays.LEGACY_DEFAULT_STREAM  # v2: no stream given, none asked for

    class CupyLikeStream:
        ptr = 1234

    fake_scene.trace(FakeCAI(o, stream=5), FakeCAI(d, stream=5), stream=CupyLikeStream())
    assert fake_scene._h.calls[-1]["stream"] == 1234  # the caller's stream wins


@pytest.mark.parametrize("make, error, match", [
    (lambda r: FakeCAI(r.astype(np.float64)), TypeError, "float32"),
    (lambda r: FakeCAI(r[:, 0:7].copy()), ValueError, r"shape \(N, 8\)"),
    (lambda r: FakeCAI(np.asfortranarray(r)), ValueError, "contiguous"),
    (lambda r: FakeCAI(r, mask=(0, False)), ValueError, "masked"),
    (lambda r: FakeCAI(r, version=4), TypeError, "version"),
    (lambda r: FakeCAI(r, stream=0), ValueError, "stream"),
    (lambda r: FakeDLPack(r.astype(np.float64)), TypeError, "float32"),
    (lambda r: FakeDLPack(r, device=(4, 0)), TypeError, "neither the CPU nor CUDA"),
])
def test_device_input_errors(fake_scene, rays, make, error, match):
    with pytest.raises(error, match=match):
        fake_scene.trace(make(rays))


def test_single_row_stride(fake_scene, rays):
    one = np.lib.stride_tricks.as_strided(rays[:1], strides=(0, 4))
    fake_scene.trace(FakeCAI(one))
    assert fake_scene._h.calls[-1]["org_row"] == 32 and fake_scene._h.calls[-1]["n"] == 1


def test_mixed_host_and_device(fake_scene, rays):
    with pytest.raises(TypeError, match="both be host arrays or both device arrays"):
        fake_scene.trace(FakeCAI(np.ascontiguousarray(rays[:, 0:3])), rays[:, 4:7])


def test_dlpack_input_names_our_stream(fake_scene, rays):
    t = FakeDLPack(rays)
    fake_scene.trace(t)
    assert t.streams == [_arrays.LEGACY_DEFAULT_STREAM]
    assert fake_scene._h.calls[-1]["org"] == rays.ctypes.data and fake_scene._h.calls[-1]["org_row"] == 32
    t2 = FakeDLPack(rays[::2])  # strided rows: passed with their stride, packed on the device
    fake_scene.trace(t2, stream=99)
    assert t2.streams == [99] and fake_scene._h.calls[-1]["org_row"] == 64


def test_not_on_device(bunny_file, rays):
    scene = cwbvh.open(bunny_file)
    scene._h = RecordingHandle(scene._h, on_device=False)
    with pytest.raises(ValueError, match="to_device"):
        scene.trace(FakeCAI(rays))
    scene._h.real.close()


def test_to_device_without_gpu(bunny):
    status, why = cwbvh.gpu_status()
    if status == "ready":
        pytest.skip("a GPU is present: test_gpu_trace_matches_cpu covers it")
    with pytest.raises(cwbvh.Error, match="no GPU path"):
        bunny.to_device()
    assert why


def test_device_array_dlpack_round_trip():
    host = np.arange(32, dtype=np.float32).reshape(8, 4)
    arr = _arrays.DeviceArray(host, host.ctypes.data + 4, (8,), (16,), "<f4", 0, None)
    arr._device_type = _arrays.KDL_CPU  # let numpy consume it
    view = np.from_dlpack(arr)
    assert np.shares_memory(view, host) and np.array_equal(view, host[:, 1])
    info = _cwbvh.dlpack_info(arr.__dlpack__())
    assert info["ptr"] == host.ctypes.data + 4 and info["strides"] == (4,) and info["dtype"] == (2, 32, 1)
    del view, arr  # the capsule's deleter releases its owner reference
    assert host.sum() > 0


def test_stream_handles():
    assert _arrays.stream_handle(None) is None and _arrays.stream_handle(5) == 5

    class Torch:
        cuda_stream = 11

    class Numba:
        class handle:  # noqa: N801 - ctypes.c_void_p-like
            value = 12

    assert _arrays.stream_handle(Torch()) == 11 and _arrays.stream_handle(Numba()) == 12
    with pytest.raises(TypeError):
        _arrays.stream_handle("default")


@pytest.mark.skipif(cwbvh.gpu_status()[0] != "ready", reason="needs a GPU (the device path waits for one)")
def test_gpu_trace_matches_cpu(bunny_file):
    cupy = pytest.importorskip("cupy")
    with cwbvh.open(bunny_file) as scene:
        rays = cwbvh.camera_rays(scene, width=256, height=256)
        expected = scene.trace(rays).records.view(np.uint32)
        scene.to_device()
        got = scene.trace(cupy.asarray(rays))
        assert np.array_equal(cupy.asnumpy(got.records).view(np.uint32), expected)
        split = scene.trace(cupy.asarray(rays[:, 0:3]), cupy.asarray(rays[:, 4:7]))
        assert np.array_equal(cupy.asnumpy(split.records).view(np.uint32), expected)
