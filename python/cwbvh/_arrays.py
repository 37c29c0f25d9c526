"""Array interchange for Scene.trace: host arrays (numpy, or anything numpy can view, DLPack CPU
tensors) and device arrays (``__cuda_array_interface__`` versions 0-3, or DLPack CUDA tensors),
and the device arrays trace returns (DeviceArray: both interfaces, converted to the caller's
library when it is CuPy, PyTorch or Numba).

Everything here is plain Python over the module's DLPack helpers, so the interface handling is
tested on machines without a GPU (python/tests/test_device_interface.py).
"""

import numpy as np

from . import _cwbvh

KDL_CPU, KDL_CUDA, KDL_CUDA_HOST, KDL_CUDA_MANAGED = 1, 2, 3, 13
LEGACY_DEFAULT_STREAM = 1  # CUDA array interface / DLPack: 1 = legacy default stream

_DLPACK_TYPES = {(2, 32, 1): "<f4", (1, 32, 1): "<u4", (0, 32, 1): "<i4", (2, 64, 1): "<f8", (2, 16, 1): "<f2"}


class DeviceView:
    """A device array as trace needs it: pointer, shape, byte strides, typestr, the producer's
    stream (CUDA array interface v3) and whatever keeps the memory referenced (`keep`)."""

    __slots__ = ("ptr", "shape", "strides", "typestr", "stream", "device", "keep")

    def __init__(self, ptr, shape, strides, typestr, stream, device, keep):
        self.ptr, self.shape, self.strides, self.typestr = ptr, shape, strides, typestr
        self.stream, self.device, self.keep = stream, device, keep


def stream_handle(stream):
    """A CUDA stream as an integer handle: an int, a CuPy stream (.ptr), a PyTorch stream
    (.cuda_stream) or a Numba stream (.handle); None stays None."""
    if stream is None or isinstance(stream, int):
        if isinstance(stream, bool):
            raise TypeError("stream: expected an integer handle or a stream object, got bool")
        return stream
    for attr in ("ptr", "cuda_stream"):
        if hasattr(stream, attr):
            return int(getattr(stream, attr))
    handle = getattr(stream, "handle", None)
    if handle is not None:
        return int(getattr(handle, "value", handle) or 0)
    raise TypeError("stream: expected an integer handle or a CuPy/PyTorch/Numba stream, got %s"
                    % type(stream).__name__)


def _c_strides(shape, itemsize):
    strides, step = [], itemsize
    for extent in reversed(shape):
        strides.append(step)
        step *= max(int(extent), 1)
    return tuple(reversed(strides))


def _from_cai(obj, name):
    cai = obj.__cuda_array_interface__
    if not isinstance(cai, dict):
        raise TypeError("%s: __cuda_array_interface__ is not a dict" % name)
    for key in ("shape", "typestr", "data"):
        if key not in cai:
            raise TypeError("%s: __cuda_array_interface__ has no '%s'" % (name, key))
    version = cai.get("version", 0)
    if not isinstance(version, int) or version < 0 or version > 3:
        raise TypeError("%s: __cuda_array_interface__ version %r is not supported (0-3)" % (name, version))
    if cai.get("mask") is not None:
        raise ValueError("%s: masked device arrays are not supported" % name)
    shape = tuple(int(s) for s in cai["shape"])
    typestr = np.dtype(cai["typestr"]).str
    ptr = int(cai["data"][0])
    strides = cai.get("strides")
    strides = _c_strides(shape, np.dtype(typestr).itemsize) if strides is None else tuple(int(s) for s in strides)
    stream = cai.get("stream") if version >= 3 else None
    if stream is not None and (not isinstance(stream, int) or stream == 0):
        raise ValueError("%s: __cuda_array_interface__ stream must be None or a nonzero integer, got %r"
                         % (name, stream))
    return DeviceView(ptr, shape, strides, typestr, stream, None, obj)


def _from_dlpack(obj, name, device_type, device_id, stream):
    # The consumer names its stream: the producer makes the data ready on it (DLPack protocol).
    capsule = obj.__dlpack__(stream=LEGACY_DEFAULT_STREAM if stream is None else stream)
    info = _cwbvh.dlpack_info(capsule)
    if (info["device_type"], info["device_id"]) != (device_type, device_id):
        raise ValueError("%s: __dlpack_device__() says %r but the tensor is on %r"
                         % (name, (device_type, device_id), (info["device_type"], info["device_id"])))
    dtype = tuple(info["dtype"])
    if dtype not in _DLPACK_TYPES:
        raise TypeError("%s: DLPack dtype (code, bits, lanes) = %r is not supported" % (name, dtype))
    typestr = _DLPACK_TYPES[dtype]
    itemsize = np.dtype(typestr).itemsize
    shape = tuple(info["shape"])
    strides = _c_strides(shape, itemsize) if info["strides"] is None else tuple(s * itemsize for s in info["strides"])
    return DeviceView(info["ptr"], shape, strides, typestr, stream, device_id, capsule)


def device_view(obj, name, stream=None):
    """The DeviceView of `obj`, or None for a host array (numpy, buffers, DLPack CPU tensors)."""
    if isinstance(obj, np.ndarray):
        return None
    if hasattr(obj, "__cuda_array_interface__"):
        return _from_cai(obj, name)
    if hasattr(obj, "__dlpack_device__") and hasattr(obj, "__dlpack__"):
        device_type, device_id = obj.__dlpack_device__()
        if device_type in (KDL_CUDA, KDL_CUDA_MANAGED):
            return _from_dlpack(obj, name, int(device_type), int(device_id), stream)
        if device_type not in (KDL_CPU, KDL_CUDA_HOST):
            raise TypeError("%s: DLPack device type %d is neither the CPU nor CUDA" % (name, device_type))
    return None


def host_array(obj, name):
    """`obj` as a numpy array without a copy (TypeError for what numpy cannot view, or views as
    objects or text: None, a str)."""
    if isinstance(obj, np.ndarray):
        return obj
    if hasattr(obj, "__dlpack__") and not hasattr(obj, "__array_interface__"):
        return np.from_dlpack(obj)
    try:
        array = np.asarray(obj)
    except Exception as e:  # noqa: BLE001 - numpy raises many kinds
        raise TypeError("%s: expected an array, got %s (%s)" % (name, type(obj).__name__, e)) from None
    if array.dtype.kind in "OUSV":
        raise TypeError("%s: expected a float32 array, got %s" % (name, type(obj).__name__))
    return array


def check_device_rays(view, name, cols):
    """Shape (N, cols), float32, the row's elements 4 bytes apart (the device packing copies rows)."""
    if view.typestr != "<f4":
        raise TypeError("%s: expected float32 ('<f4'), got %s" % (name, view.typestr))
    if len(view.shape) != 2 or view.shape[1] != cols:
        raise ValueError("%s: expected shape (N, %d), got %s" % (name, cols, view.shape))
    if view.shape[0] > 1 and view.strides[0] < 4 * cols or (cols > 1 and view.strides[1] != 4):
        raise ValueError("%s: the %d floats of a row must be contiguous (strides %s); copy it with "
                         ".copy() or ascontiguousarray first" % (name, cols, view.strides))


class DeviceArray:
    """Device memory trace returned: exposes __cuda_array_interface__ (v3, with the stream the
    work was enqueued on) and DLPack (__dlpack__, __dlpack_device__). Keeps `owner` (the module's
    DeviceBuffer) alive while any view or consumer holds it."""

    def __init__(self, owner, ptr, shape, strides, typestr, device, stream):
        self._owner, self.ptr, self.shape, self.strides = owner, ptr, tuple(shape), tuple(strides)
        self.typestr, self.device, self.stream = typestr, device, stream
        self._device_type = KDL_CUDA

    @property
    def dtype(self):
        return np.dtype(self.typestr)

    def __len__(self):
        return self.shape[0]

    @property
    def __cuda_array_interface__(self):
        return {"shape": self.shape, "typestr": self.typestr, "data": (self.ptr, False), "version": 3,
                "strides": self.strides, "stream": self.stream}

    def __dlpack_device__(self):
        return (self._device_type, self.device)

    def __dlpack__(self, stream=None):
        consumer = stream_handle(stream)
        if self._device_type == KDL_CUDA and consumer not in (None, -1) and consumer != self.stream:
            _cwbvh.stream_order(self.device, self.stream or LEGACY_DEFAULT_STREAM, consumer)
        code = {"<f4": 2, "<u4": 1}[self.typestr]
        itemsize = self.dtype.itemsize
        return _cwbvh.dlpack_capsule(self, self.ptr, self._device_type, self.device, list(self.shape),
                                     [s // itemsize for s in self.strides], code, 8 * itemsize)

    def __repr__(self):
        return "DeviceArray(shape=%s, dtype=%s, device=%d)" % (self.shape, self.typestr, self.device)


def like(array, reference):
    """`array` (a DeviceArray) in the library `reference` came from when that is CuPy, PyTorch or
    Numba (zero-copy); the DeviceArray itself otherwise."""
    module = type(reference).__module__.split(".")[0]
    try:
        if module == "cupy":
            import cupy
            return cupy.asarray(array)
        if module == "torch":
            import torch
            return torch.from_dlpack(array)
        if module == "numba":
            from numba import cuda
            return cuda.as_cuda_array(array)
    except ImportError:
        pass
    return array
