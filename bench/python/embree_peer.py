"""A thin Python wrapper over Debian's Embree 3 (libembree3.so.3) with numpy arrays, through
ctypes: what embreex/trimesh do, for the Python benchmark and its agreement check. Benchmark
peer only, not part of the cwbvh package.

Rays are traced with rtcIntersect1M (a stream of RTCRayHit records, Embree's own loop over them)
on the calling thread; `threads` Python threads trace contiguous parts at once (ctypes releases
the GIL during the call). The ray mask is set to all ones: Debian builds Embree with ray masks
enabled (rtcGetDeviceProperty(RAY_MASK_SUPPORTED) == 1), and a ray whose mask is 0 hits nothing.
That is what makes Open3D 0.16's RaycastingScene.cast_rays miss everything on Debian 12
(open3d_check.py).
"""

import ctypes
import threading
import time

import numpy as np

RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX, RTC_BUFFER_TYPE_VERTEX = 0, 1
RTC_FORMAT_UINT3, RTC_FORMAT_FLOAT3 = 0x5003, 0x9003
RTC_BUILD_QUALITY = {"low": 0, "medium": 1, "high": 2}
RTC_SCENE_FLAG_ROBUST = 1 << 2
RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED = 64
RTC_INVALID_GEOMETRY_ID = 0xFFFFFFFF
MISS = 0xFFFFFFFF

# RTCRayHit: RTCRay (org, tnear, dir, time, tfar, mask, id, flags: 48 bytes) + RTCHit (Ng, u, v,
# primID, geomID, instID[1]: 32 bytes); 80 bytes, 16-byte aligned. Columns of a (N, 20) float32.
_RAYHIT_FLOATS = 20
_TFAR, _MASK, _U, _V, _PRIM, _GEOM = 8, 9, 15, 16, 17, 18


class _IntersectContext(ctypes.Structure):  # rtcInitIntersectContext (inline in the header)
    _fields_ = [("flags", ctypes.c_int), ("filter", ctypes.c_void_p), ("instID", ctypes.c_uint * 1)]


def _lib():
    lib = ctypes.CDLL("libembree3.so.3")
    vp, u, sz = ctypes.c_void_p, ctypes.c_uint, ctypes.c_size_t
    lib.rtcNewDevice.restype = vp
    lib.rtcNewDevice.argtypes = [ctypes.c_char_p]
    lib.rtcGetDeviceProperty.restype = ctypes.c_ssize_t
    lib.rtcGetDeviceProperty.argtypes = [vp, ctypes.c_int]
    lib.rtcNewScene.restype = vp
    lib.rtcNewScene.argtypes = [vp]
    lib.rtcSetSceneBuildQuality.argtypes = [vp, ctypes.c_int]
    lib.rtcSetSceneFlags.argtypes = [vp, ctypes.c_int]
    lib.rtcNewGeometry.restype = vp
    lib.rtcNewGeometry.argtypes = [vp, ctypes.c_int]
    lib.rtcSetNewGeometryBuffer.restype = vp
    lib.rtcSetNewGeometryBuffer.argtypes = [vp, ctypes.c_int, u, ctypes.c_int, sz, sz]
    for name in ("rtcCommitGeometry", "rtcReleaseGeometry", "rtcCommitScene", "rtcReleaseScene",
                 "rtcReleaseDevice"):
        getattr(lib, name).argtypes = [vp]
    lib.rtcAttachGeometry.restype = u
    lib.rtcAttachGeometry.argtypes = [vp, vp]
    lib.rtcIntersect1M.argtypes = [vp, ctypes.POINTER(_IntersectContext), vp, u, sz]
    return lib


class EmbreeScene:
    """Embree's BVH over a triangle mesh: vertices (V, 3) float32, indices (T, 3) uint32 (a hit's
    prim is the row of `indices`). quality: Embree's build quality; threads: its build threads."""

    def __init__(self, vertices, indices, quality="medium", threads=None, robust=False):
        self.lib = _lib()
        config = ("threads=%d" % threads).encode() if threads else None
        self.device = self.lib.rtcNewDevice(config)
        if not self.device:
            raise RuntimeError("rtcNewDevice failed")
        self.ray_mask_supported = bool(self.lib.rtcGetDeviceProperty(self.device, RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED))
        vertices = np.ascontiguousarray(vertices, dtype=np.float32)
        indices = np.ascontiguousarray(indices, dtype=np.uint32)
        self.scene = self.lib.rtcNewScene(self.device)
        self.lib.rtcSetSceneBuildQuality(self.scene, RTC_BUILD_QUALITY[quality])
        if robust:
            self.lib.rtcSetSceneFlags(self.scene, RTC_SCENE_FLAG_ROBUST)
        geom = self.lib.rtcNewGeometry(self.device, RTC_GEOMETRY_TYPE_TRIANGLE)
        # Embree may read 16 bytes at the last vertex: one float3 of padding.
        vb = self.lib.rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 12, len(vertices) + 1)
        ctypes.memmove(vb, vertices.ctypes.data, vertices.nbytes)
        ib = self.lib.rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 12, len(indices))
        ctypes.memmove(ib, indices.ctypes.data, indices.nbytes)
        self.lib.rtcCommitGeometry(geom)
        self.lib.rtcAttachGeometry(self.scene, geom)
        self.lib.rtcReleaseGeometry(geom)
        self.lib.rtcCommitScene(self.scene)

    def close(self):
        if self.scene:
            self.lib.rtcReleaseScene(self.scene)
            self.lib.rtcReleaseDevice(self.device)
            self.scene = self.device = None

    def __del__(self):
        self.close()

    def intersect(self, rays, threads=1, mask=0xFFFFFFFF):
        """Closest hits of (N, 8) float32 rays (cwbvh's ray-file layout): (t, u, v, prim) like
        cwbvh's Scene.trace (t = inf, prim = MISS for a miss). `mask` is the rays' mask.
        last_trace_seconds: the wall time of the rtcIntersect1M calls alone (without filling the
        RTCRayHit records and reading the hits back, which the wrapper does with numpy)."""
        rays = np.asarray(rays, dtype=np.float32)
        n = len(rays)
        raw = np.empty(n * _RAYHIT_FLOATS + 4, dtype=np.float32)  # 16-byte alignment by offset
        off = (-raw.ctypes.data % 16) // 4
        rh = raw[off:off + n * _RAYHIT_FLOATS].reshape(n, _RAYHIT_FLOATS)
        rh[:, 0:4] = rays[:, 0:4]            # org, tnear
        rh[:, 4:7] = rays[:, 4:7]            # dir
        rh[:, 7] = 0.0                       # time
        rh[:, _TFAR] = rays[:, 7]
        bits = rh.view(np.uint32)
        bits[:, _MASK] = mask
        bits[:, 10] = 0                      # id
        bits[:, 11] = 0                      # flags
        bits[:, _GEOM] = RTC_INVALID_GEOMETRY_ID
        bits[:, 19] = RTC_INVALID_GEOMETRY_ID
        start = time.perf_counter()
        self._run(rh, threads)
        self.last_trace_seconds = time.perf_counter() - start  # rtcIntersect1M calls alone
        hit = bits[:, _GEOM] != RTC_INVALID_GEOMETRY_ID
        t = np.where(hit, rh[:, _TFAR], np.float32(np.inf)).astype(np.float32)
        u = np.where(hit, rh[:, _U], 0).astype(np.float32)
        v = np.where(hit, rh[:, _V], 0).astype(np.float32)
        prim = np.where(hit, bits[:, _PRIM], MISS).astype(np.uint32)
        return t, u, v, prim

    def _run(self, rh, threads):
        n = len(rh)
        parts = max(1, min(int(threads), n))

        def work(begin, end):
            ctx = _IntersectContext(0, None, (ctypes.c_uint * 1)(RTC_INVALID_GEOMETRY_ID))
            if end > begin:
                self.lib.rtcIntersect1M(self.scene, ctypes.byref(ctx), rh[begin:end].ctypes.data, end - begin, 80)

        bounds = [n * i // parts for i in range(parts + 1)]
        pool = [threading.Thread(target=work, args=(bounds[i], bounds[i + 1])) for i in range(1, parts)]
        for th in pool:
            th.start()
        work(bounds[0], bounds[1])
        for th in pool:
            th.join()
