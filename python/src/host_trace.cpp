// Scene.trace on the CPU: numpy rays in, Hit records out, through trace_cwbvh_cpu (cpu_trace.h),
// or trace_two_level_cpu for a two-level file (format 1.2; then also an (N,) uint32 array of the
// INST index of each hit, kInvalidIndex for a miss), multi-threaded and without the GIL.
//
// Copies: an (N, 8) float32 array in the ray-file layout (org, tmin, dir, tmax), C-contiguous and
// 4-byte aligned, is traced in place (zero-copy). Anything else (origins + directions (N, 3), or
// a strided (N, 8)) is packed once into Ray records, in parallel on the trace's threads. The hits
// are written straight into the (N, 4) float32 array returned (t, u, v, prim bits per row), which
// Python splits into views without a copy.
#include <pybind11/numpy.h>
#include <sys/mman.h>

#include <algorithm>
#include <cstdlib>
#include <new>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "common.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/kernels/two_level_file.h"
#include "scene.h"

namespace cwbvh::python {
namespace {

/// float32 in native byte order: numpy exports "f", or "=f" / "<f" for an unaligned array
/// (which the packing below copies element by element).
bool is_float32(const py::buffer_info& b) {
    return b.itemsize == 4 && (b.format == "f" || b.format == "=f" || b.format == "<f");
}

/// `what` must be a 2-D float32 array with `cols` columns (TypeError / ValueError otherwise).
py::buffer_info checked(const py::array& a, const char* what, py::ssize_t cols) {
    py::buffer_info b = a.request();
    if (!is_float32(b))
        throw py::type_error(std::string(what) + ": expected float32, got dtype " +
                             py::str(a.dtype()).cast<std::string>() + " (convert with .astype(numpy.float32))");
    if (b.ndim != 2 || b.shape[1] != cols)
        throw py::value_error(std::string(what) + ": expected shape (N, " + std::to_string(cols) + "), got " +
                              py::str(py::tuple(a.attr("shape"))).cast<std::string>());
    return b;
}

unsigned resolve_threads(unsigned threads) {
    if (threads) return threads;
    const unsigned hw = std::thread::hardware_concurrency();
    return hw ? hw : 1;
}

/// Runs fn(begin, end) over [0, n) in `threads` contiguous parts.
template <class Fn>
void parallel_parts(size_t n, unsigned threads, const Fn& fn) {
    const size_t parts = std::max<size_t>(1, std::min<size_t>(threads, n / 65536 + 1));
    std::vector<std::thread> pool;
    for (size_t p = 1; p < parts; ++p) pool.emplace_back([&, p] { fn(n * p / parts, n * (p + 1) / parts); });
    fn(0, n / parts);
    for (auto& t : pool) t.join();
}

struct FreeDeleter {
    void operator()(Ray* p) const { std::free(p); }
};
using RayBuffer = std::unique_ptr<Ray[], FreeDeleter>;

/// Uninitialised room for n rays (the packing writes every byte). Large buffers are 2 MiB aligned
/// and advised to use transparent huge pages: a fresh 32 MiB buffer (1M rays) then takes 16 page
/// faults instead of 8192, which cost ~30 ms on a loaded 2-core VM (measured: bench/python).
RayBuffer ray_buffer(size_t n) {
    constexpr size_t kHugePage = size_t(2) << 20;
    const size_t bytes = std::max<size_t>(n, 1) * sizeof(Ray);
    if (bytes < kHugePage) {
        if (void* p = std::malloc(bytes)) return RayBuffer(static_cast<Ray*>(p));
        throw std::bad_alloc();
    }
    const size_t rounded = (bytes + kHugePage - 1) / kHugePage * kHugePage;
    void* p = std::aligned_alloc(kHugePage, rounded);
    if (!p) throw std::bad_alloc();
    (void)madvise(p, rounded, MADV_HUGEPAGE);  // advice only: without THP the pages are small
    return RayBuffer(static_cast<Ray*>(p));
}

float load(const char* base, py::ssize_t row, py::ssize_t row_stride, py::ssize_t col, py::ssize_t col_stride) {
    float v;
    std::memcpy(&v, base + row * row_stride + col * col_stride, sizeof v);
    return v;
}

py::tuple trace_host(const SceneHandle& h, const py::array& origins, const py::object& directions, float tmin,
                     float tmax, bool any, bool watertight, unsigned threads, py::dict stats_out) {
    const std::shared_ptr<const File> file = h.file();  // keeps the mapping for the whole call
    const bool packed_input = directions.is_none();
    const py::buffer_info o = checked(origins, packed_input ? "rays" : "origins", packed_input ? 8 : 3);
    py::buffer_info d;
    if (!packed_input) {
        if (!py::isinstance<py::array>(directions)) throw py::type_error("directions: expected a numpy array");
        d = checked(directions.cast<py::array>(), "directions", 3);
        if (d.shape[0] != o.shape[0])
            throw py::value_error("origins and directions differ in length: " + std::to_string(o.shape[0]) + " vs " +
                                  std::to_string(d.shape[0]));
    }
    const size_t n = size_t(o.shape[0]);
    threads = resolve_threads(threads);

    py::array_t<float> hits({py::ssize_t(n), py::ssize_t(4)});
    Hit* out = reinterpret_cast<Hit*>(hits.mutable_data());
    // A two-level file: trace_two_level_cpu, with the INST index of each hit.
    TwoLevelScene two;
    const bool two_level = two_level_scene(*file, two);
    py::object instances = py::none();
    uint32_t* inst = nullptr;
    if (two_level) {
        py::array_t<uint32_t> a{py::ssize_t(n)};
        inst = a.mutable_data();
        instances = a;
    }
    const bool zero_copy = packed_input && o.strides[1] == 4 && o.strides[0] == py::ssize_t(sizeof(Ray)) &&
                           reinterpret_cast<uintptr_t>(o.ptr) % alignof(Ray) == 0;
    CpuTraceStats s;
    {
        py::gil_scoped_release release;  // the buffers stay referenced by the arrays' owners
        RayBuffer packed;
        const Ray* rays = static_cast<const Ray*>(o.ptr);
        if (!zero_copy) {
            packed = ray_buffer(n);
            const char* ob = static_cast<const char*>(o.ptr);
            const char* db = static_cast<const char*>(d.ptr);
            parallel_parts(n, threads, [&](size_t begin, size_t end) {
                for (size_t i = begin; i < end; ++i) {
                    Ray& r = packed[i];
                    const auto row = py::ssize_t(i);
                    if (packed_input) {
                        float v[8];
                        for (int k = 0; k < 8; ++k) v[k] = load(ob, row, o.strides[0], k, o.strides[1]);
                        std::memcpy(&r, v, sizeof r);
                    } else {
                        for (int k = 0; k < 3; ++k) {
                            r.org[k] = load(ob, row, o.strides[0], k, o.strides[1]);
                            r.dir[k] = load(db, row, d.strides[0], k, d.strides[1]);
                        }
                        r.tmin = tmin;
                        r.tmax = tmax;
                    }
                }
            });
            rays = packed.get();
        }
        CpuTraceOptions opt;
        opt.mode = any ? HitMode::kAny : HitMode::kClosest;
        opt.test = watertight ? TriangleTest::kWatertight : TriangleTest::kFast;
        opt.threads = threads;
        if (two_level) {
            s = trace_two_level_cpu(two, rays, out, inst, n, opt);
        } else {
            const auto nodes = file->nodes();
            const auto tris = file->triangles();
            s = trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), rays, out, n, opt);
        }
    }
    stats_out["rays"] = s.rays;
    stats_out["hits"] = s.hits;
    stats_out["invalid_rays"] = s.invalid_rays;
    stats_out["stack_overflows"] = s.stack_overflows;
    stats_out["bad_indices"] = s.bad_indices;
    stats_out["nodes_visited"] = s.nodes_visited;
    stats_out["triangles_tested"] = s.triangles_tested;
    stats_out["seconds"] = s.seconds;
    stats_out["threads"] = threads;
    stats_out["zero_copy"] = zero_copy;
    return py::make_tuple(hits, instances);
}

template <class T>
py::array records(std::vector<T>&& v, size_t cols) {
    auto* keep = new std::vector<T>(std::move(v));
    py::capsule base(keep, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array(py::dtype::of<float>(), {keep->size(), cols}, {sizeof(T), sizeof(float)},
                     reinterpret_cast<const float*>(keep->data()), base);
}

}  // namespace

void bind_host_trace(py::module_& m) {
    py::class_<SceneHandle, std::shared_ptr<SceneHandle>> cls =
        py::reinterpret_borrow<py::class_<SceneHandle, std::shared_ptr<SceneHandle>>>(m.attr("SceneHandle"));
    cls.def("trace_host", &trace_host, py::arg("origins"), py::arg("directions"), py::arg("tmin"),
            py::arg("tmax"), py::arg("any_hit"), py::arg("watertight"), py::arg("threads"), py::arg("stats"));
    m.def("read_rays", [](const std::string& path) {
        std::vector<Ray> rays;
        check(read_ray_file(path, rays));
        return records(std::move(rays), 8);
    });
    m.def("read_hits", [](const std::string& path, bool with_instances) {
        std::vector<Hit> hits;
        uint32_t flags = 0;
        if (!with_instances) {
            check(read_hit_file(path, hits, flags));  // refuses a 1.1 file (instances) by name
            return py::make_tuple(records(std::move(hits), 4), flags);
        }
        std::vector<uint32_t> instances;
        check(read_hit_file(path, hits, instances, flags));
        py::object inst = py::none();  // a 1.0 file (no instances)
        if (!instances.empty()) {
            py::array_t<uint32_t> a{py::ssize_t(instances.size())};
            std::memcpy(a.mutable_data(), instances.data(), instances.size() * sizeof(uint32_t));
            inst = a;
        }
        return py::make_tuple(records(std::move(hits), 4), inst, flags);
    }, py::arg("path"), py::arg("with_instances") = false);
}

}  // namespace cwbvh::python
