// The GPU side of the Scene: to_device() (DeviceScene::upload, once), trace_device() over device
// pointers that __init__.py / _arrays.py took from __cuda_array_interface__ or DLPack, and
// gpu_status(). Everything is enqueued on the caller's stream (a cudaStream_t handle as an
// integer; 1 = legacy default, 2 = per-thread default, as in the CUDA array interface): no host
// round trip, no synchronisation. A two-level file (format 1.2) runs trace_two_level, which also
// writes each hit's INST index (after the Hit records, in the same buffer).
//
// Copies on the device: (N, 8) rays with 32-byte rows are traced in place. Strided (N, 8) rays,
// or origins + directions (N, 3) (any row stride, 4-byte element stride), are packed once into
// Ray records by cudaMemcpy2DAsync on the stream (tmin and tmax are written into the first ray
// and copied onward in doubling blocks), in a stream-ordered scratch buffer. The hits are one
// (N, 4) buffer of Hit records (DeviceBuffer), which Python exposes as t, u, v, prim views.
//
// Without CUDA (no nvcc at configure time) the same functions exist and raise cwbvh.Error with
// gpu_status()'s reason.
#include <pybind11/stl.h>

#include <cstdint>

#include "common.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "scene.h"
#if defined(CWBVH_HAVE_CUDA)
#include <cuda_runtime_api.h>

#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/trace.h"
#endif

namespace cwbvh::python {
namespace {

/// Device memory of the hits (cudaMalloc'd on `device`); freed when the last Python view of it goes.
class DeviceBuffer {
public:
    DeviceBuffer(void* ptr, size_t bytes, int device) : ptr_(ptr), bytes_(bytes), device_(device) {}
    DeviceBuffer(const DeviceBuffer&) = delete;
    DeviceBuffer& operator=(const DeviceBuffer&) = delete;
    ~DeviceBuffer() {
#if defined(CWBVH_HAVE_CUDA)
        int current = 0;
        if (cudaGetDevice(&current) == cudaSuccess && current != device_) CWBVH_CUDA_WARN(cudaSetDevice(device_));
        CWBVH_CUDA_WARN(cudaFree(ptr_));
        if (current != device_) CWBVH_CUDA_WARN(cudaSetDevice(current));
#endif
    }
    uintptr_t ptr() const { return reinterpret_cast<uintptr_t>(ptr_); }
    size_t bytes() const { return bytes_; }
    int device() const { return device_; }

private:
    void* ptr_;
    size_t bytes_;
    int device_;
};

[[noreturn]] void no_gpu() {
    std::string why;
    gpu_status(why);
    throw ResultError(Result::fail(Status::kDeviceError, 0, "no GPU path: " + why));
}

#if defined(CWBVH_HAVE_CUDA)
/// Makes `device` current for the scope and restores the caller's device.
class DeviceScope {
public:
    explicit DeviceScope(int device) {
        CWBVH_CUDA_CHECK(cudaGetDevice(&previous_));
        if (previous_ != device) CWBVH_CUDA_CHECK(cudaSetDevice(device));
    }
    ~DeviceScope() { CWBVH_CUDA_WARN(cudaSetDevice(previous_)); }
    DeviceScope(const DeviceScope&) = delete;
    DeviceScope& operator=(const DeviceScope&) = delete;

private:
    int previous_ = 0;
};

void require_device_pointer(uintptr_t p, int device, const char* what) {
    cudaPointerAttributes a{};
    if (cudaPointerGetAttributes(&a, reinterpret_cast<const void*>(p)) != cudaSuccess) {
        (void)cudaGetLastError();
        throw py::value_error(std::string(what) + ": not a CUDA device pointer");
    }
    if (a.type != cudaMemoryTypeDevice && a.type != cudaMemoryTypeManaged)
        throw py::value_error(std::string(what) + ": not device memory (host memory goes through numpy)");
    if (a.device != device)
        throw py::value_error(std::string(what) + ": on device " + std::to_string(a.device) +
                              ", the Scene is on device " + std::to_string(device));
}

std::shared_ptr<DeviceBuffer> trace_device(const SceneHandle& h, uintptr_t org, int64_t org_row, uintptr_t dir,
                                           int64_t dir_row, size_t n, float tmin, float tmax, uintptr_t stream,
                                           bool any, bool watertight) {
    (void)h.file();  // ValueError when closed
    const std::shared_ptr<const DeviceScene> scene = h.device();
    if (!scene) throw py::value_error(h.path() + ": the Scene is not on the GPU: call Scene.to_device() first");
    py::gil_scoped_release release;
    try {
        const DeviceScope scope(scene->device());
        require_device_pointer(org, scene->device(), dir ? "origins" : "rays");
        if (dir) require_device_pointer(dir, scene->device(), "directions");
        const auto s = reinterpret_cast<cudaStream_t>(stream);
        // A two-level scene: the n INST indices follow the n Hit records in the same buffer
        // (byte offset 16 n; __init__.py views them there).
        const bool two_level = scene->has_two_level();
        const size_t hit_bytes = n * sizeof(Hit);
        const size_t bytes = hit_bytes + (two_level ? n * sizeof(uint32_t) : 0);
        void* hits = nullptr;
        CWBVH_CUDA_CHECK(cudaMalloc(&hits, std::max<size_t>(bytes, sizeof(Hit))));
        auto out = std::make_shared<DeviceBuffer>(hits, bytes, scene->device());
        if (n == 0) return out;
        const Ray* rays = reinterpret_cast<const Ray*>(org);
        void* scratch = nullptr;
        // In place only with 32-byte rows at a 16-byte aligned address (the kernels load a Ray as two
        // 16-byte vectors); anything else is packed.
        if (dir || org_row != int64_t(sizeof(Ray)) || org % 16 != 0) {
            CWBVH_CUDA_CHECK(cudaMallocAsync(&scratch, n * sizeof(Ray), s));
            auto* base = static_cast<char*>(scratch);
            constexpr auto d2d = cudaMemcpyDeviceToDevice;
            if (!dir) {
                CWBVH_CUDA_CHECK(cudaMemcpy2DAsync(base, sizeof(Ray), reinterpret_cast<const void*>(org),
                                                   size_t(org_row), sizeof(Ray), n, d2d, s));
            } else {
                CWBVH_CUDA_CHECK(cudaMemcpy2DAsync(base + offsetof(Ray, org), sizeof(Ray),
                                                   reinterpret_cast<const void*>(org), size_t(org_row),
                                                   3 * sizeof(float), n, d2d, s));
                CWBVH_CUDA_CHECK(cudaMemcpy2DAsync(base + offsetof(Ray, dir), sizeof(Ray),
                                                   reinterpret_cast<const void*>(dir), size_t(dir_row),
                                                   3 * sizeof(float), n, d2d, s));
                // Pageable source: cudaMemcpyAsync returns once tmin/tmax are staged.
                CWBVH_CUDA_CHECK(cudaMemcpyAsync(base + offsetof(Ray, tmin), &tmin, sizeof(float),
                                                 cudaMemcpyHostToDevice, s));
                CWBVH_CUDA_CHECK(cudaMemcpyAsync(base + offsetof(Ray, tmax), &tmax, sizeof(float),
                                                 cudaMemcpyHostToDevice, s));
                for (size_t k = 1; k < n; k *= 2) {  // rays [0, k) hold them: copy to [k, 2k)
                    const size_t rows = std::min(k, n - k);
                    for (size_t field : {offsetof(Ray, tmin), offsetof(Ray, tmax)})
                        CWBVH_CUDA_CHECK(cudaMemcpy2DAsync(base + k * sizeof(Ray) + field, sizeof(Ray), base + field,
                                                           sizeof(Ray), sizeof(float), rows, d2d, s));
                }
            }
            rays = static_cast<const Ray*>(scratch);
        }
        TraceOptions o;
        o.test = watertight ? TriangleTest::kWatertight : TriangleTest::kFast;
        if (two_level) {
            trace_two_level(*scene, rays, static_cast<Hit*>(hits),
                            reinterpret_cast<uint32_t*>(static_cast<char*>(hits) + hit_bytes), n,
                            any ? Query::kAny : Query::kClosest, s, o);
        } else {
            trace(*scene, rays, static_cast<Hit*>(hits), n, any ? Query::kAny : Query::kClosest, s, o);
        }
        if (scratch) CWBVH_CUDA_CHECK(cudaFreeAsync(scratch, s));
        return out;
    } catch (const CudaError& e) {
        throw ResultError(Result::fail(Status::kDeviceError, 0, e.what()));
    }
}

/// Makes `consumer` wait for the work enqueued so far on `producer` (DLPack export to a consumer
/// that names another stream).
void stream_order(int device, uintptr_t producer, uintptr_t consumer) {
    try {
        const DeviceScope scope(device);
        cudaEvent_t e = nullptr;
        CWBVH_CUDA_CHECK(cudaEventCreateWithFlags(&e, cudaEventDisableTiming));
        CWBVH_CUDA_CHECK(cudaEventRecord(e, reinterpret_cast<cudaStream_t>(producer)));
        CWBVH_CUDA_CHECK(cudaStreamWaitEvent(reinterpret_cast<cudaStream_t>(consumer), e, 0));
        CWBVH_CUDA_CHECK(cudaEventDestroy(e));
    } catch (const CudaError& e) {
        throw ResultError(Result::fail(Status::kDeviceError, 0, e.what()));
    }
}

void to_device(SceneHandle& h, int device) {
    if (h.device()) return;  // uploaded once
    const std::shared_ptr<const File> file = h.file();
    std::string why;
    if (!gpu_available(why)) no_gpu();
    Expected<DeviceScene> up = [&] {
        py::gil_scoped_release release;
        UploadOptions o;
        o.device = device;
        return DeviceScene::upload(*file, o);
    }();
    if (!up.ok()) throw ResultError(up.error());
    h.set_device(std::make_shared<const DeviceScene>(std::move(*up)));
}
#else
std::shared_ptr<DeviceBuffer> trace_device(const SceneHandle&, uintptr_t, int64_t, uintptr_t, int64_t, size_t, float,
                                           float, uintptr_t, bool, bool) {
    no_gpu();
}
void to_device(SceneHandle&, int) { no_gpu(); }
void stream_order(int, uintptr_t, uintptr_t) { no_gpu(); }
#endif

}  // namespace

void bind_device(py::module_& m) {
    py::class_<DeviceBuffer, std::shared_ptr<DeviceBuffer>>(m, "DeviceBuffer")
        .def_property_readonly("ptr", &DeviceBuffer::ptr)
        .def_property_readonly("nbytes", &DeviceBuffer::bytes)
        .def_property_readonly("device", &DeviceBuffer::device);
    auto cls = py::reinterpret_borrow<py::class_<SceneHandle, std::shared_ptr<SceneHandle>>>(m.attr("SceneHandle"));
    cls.def("to_device", &to_device, py::arg("device") = -1)
        .def_property_readonly("on_device", [](const SceneHandle& h) { return h.device() != nullptr; })
        .def_property_readonly("device_id", [](const SceneHandle& h) {
            const auto d = h.device();
            return d ? d->device() : -1;
        })
        .def("trace_device", &trace_device, py::arg("org"), py::arg("org_row_stride"), py::arg("dir"),
             py::arg("dir_row_stride"), py::arg("n"), py::arg("tmin"), py::arg("tmax"), py::arg("stream"),
             py::arg("any_hit"), py::arg("watertight"));
    m.def("stream_order", &stream_order, py::arg("device"), py::arg("producer"), py::arg("consumer"));
    m.def("gpu_status", [] {
        std::string why;
        const GpuStatus s = gpu_status(why);
        const char* names[] = {"ready", "no device", "no cuda", "unusable"};
        return py::make_tuple(names[uint32_t(s) & 3u], why);
    });
#if defined(CWBVH_HAVE_CUDA)
    m.attr("built_with_cuda") = true;
#else
    m.attr("built_with_cuda") = false;
#endif
}

}  // namespace cwbvh::python
