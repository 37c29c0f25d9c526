// DLPack (https://dmlc.github.io/dlpack/latest/): reading a producer's capsule (trace's inputs
// from PyTorch, JAX, CuPy, ...) and making capsules for our outputs (DeviceArray.__dlpack__).
// The structs are DLPack's stable ABI (v0.x DLManagedTensor, the "dltensor" capsule), declared
// here: Debian packages no dlpack header.
#include <pybind11/stl.h>

#include <cstdint>
#include <optional>
#include <vector>

#include "common.h"

namespace cwbvh::python {
namespace {

struct DLDevice {
    int32_t device_type;  // kDLCPU = 1, kDLCUDA = 2, kDLCUDAHost = 3, kDLCUDAManaged = 13
    int32_t device_id;
};
struct DLDataType {
    uint8_t code;  // kDLInt = 0, kDLUInt = 1, kDLFloat = 2
    uint8_t bits;
    uint16_t lanes;
};
struct DLTensor {
    void* data;
    DLDevice device;
    int32_t ndim;
    DLDataType dtype;
    int64_t* shape;
    int64_t* strides;  // in elements; nullptr: C-contiguous
    uint64_t byte_offset;
};
struct DLManagedTensor {
    DLTensor dl_tensor;
    void* manager_ctx;
    void (*deleter)(DLManagedTensor* self);
};

/// What an exported capsule owns: the tensor, its shape and strides, and a reference to the
/// Python object that owns the memory.
struct Export {
    DLManagedTensor tensor{};
    std::vector<int64_t> shape, strides;
    PyObject* owner = nullptr;
};

void delete_export(DLManagedTensor* t) {
    auto* e = static_cast<Export*>(t->manager_ctx);
    {
        py::gil_scoped_acquire gil;  // a consumer may call the deleter from any thread
        Py_XDECREF(e->owner);
    }
    delete e;
}

/// Capsule destructor: a capsule nobody consumed (still named "dltensor") frees its tensor.
void capsule_destructor(PyObject* capsule) {
    if (!PyCapsule_IsValid(capsule, "dltensor")) return;  // consumed: renamed "used_dltensor"
    auto* t = static_cast<DLManagedTensor*>(PyCapsule_GetPointer(capsule, "dltensor"));
    if (t && t->deleter) t->deleter(t);
}

py::dict tensor_info(const py::capsule& capsule) {
    if (!PyCapsule_IsValid(capsule.ptr(), "dltensor"))
        throw py::value_error("__dlpack__() did not return an unconsumed 'dltensor' capsule");
    const auto* t = static_cast<const DLManagedTensor*>(PyCapsule_GetPointer(capsule.ptr(), "dltensor"));
    const DLTensor& d = t->dl_tensor;
    if (d.ndim < 0 || d.ndim > 32) throw py::value_error("DLPack tensor: bad ndim " + std::to_string(d.ndim));
    py::list shape, strides;
    for (int i = 0; i < d.ndim; ++i) {
        shape.append(d.shape[i]);
        if (d.strides) strides.append(d.strides[i]);
    }
    py::dict out;
    out["ptr"] = reinterpret_cast<uintptr_t>(d.data) + d.byte_offset;
    out["device_type"] = d.device.device_type;
    out["device_id"] = d.device.device_id;
    out["shape"] = py::tuple(shape);
    out["strides"] = d.strides ? py::object(py::tuple(strides)) : py::object(py::none());
    out["dtype"] = py::make_tuple(d.dtype.code, d.dtype.bits, d.dtype.lanes);
    return out;
}

py::capsule make_capsule(const py::object& owner, uintptr_t ptr, int device_type, int device_id,
                         const std::vector<int64_t>& shape, const std::vector<int64_t>& strides, int code, int bits) {
    if (shape.size() != strides.size()) throw py::value_error("dlpack_capsule: shape and strides differ in length");
    auto* e = new Export;
    e->shape = shape;
    e->strides = strides;
    e->owner = owner.ptr();
    Py_INCREF(e->owner);
    DLTensor& d = e->tensor.dl_tensor;
    d.data = reinterpret_cast<void*>(ptr);
    d.device = {device_type, device_id};
    d.ndim = int32_t(shape.size());
    d.dtype = {uint8_t(code), uint8_t(bits), 1};
    d.shape = e->shape.data();
    d.strides = e->strides.data();
    d.byte_offset = 0;
    e->tensor.manager_ctx = e;
    e->tensor.deleter = &delete_export;
    PyObject* c = PyCapsule_New(&e->tensor, "dltensor", &capsule_destructor);
    if (!c) {
        delete_export(&e->tensor);
        throw py::error_already_set();
    }
    return py::reinterpret_steal<py::capsule>(c);
}

}  // namespace

void bind_dlpack(py::module_& m) {
    m.def("dlpack_info", &tensor_info, py::arg("capsule"));
    m.def("dlpack_capsule", &make_capsule, py::arg("owner"), py::arg("ptr"), py::arg("device_type"),
          py::arg("device_id"), py::arg("shape"), py::arg("strides"), py::arg("code"), py::arg("bits"));
}

}  // namespace cwbvh::python
