// Plain C++ entry point to the GPU tracer (no CUDA types; callers need neither
// nvcc nor the CUDA headers). Used by `cwbvh trace --gpu`, the minimal renderer
// and the GPU check. Always linkable: target cwbvh_gpu_trace; in a build without
// CUDA, gpu_status() returns kNoCuda, gpu_available() false ("built without CUDA")
// and trace_on_gpu() a kDeviceError.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "cwbvh/format/status.h"
#include "cwbvh/kernels/kernel_options.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

class File;

enum class GpuKernel : uint32_t { kCwbvh = 0, kBvh2 = 1 };

/// CwbvhKernelOptions (kernel_options.h): the CWBVH kernel's A/B options, for a single-level file.
struct GpuTraceOptions : CwbvhKernelOptions {
    bool any = false;                          ///< any-hit (occlusion) instead of closest hit
    GpuKernel kernel = GpuKernel::kCwbvh;
    TriangleTest test = TriangleTest::kWatertight;
    int repeat = 1;                            ///< timed kernel runs, after one untimed warm-up run
    int device = -1;                           ///< CUDA device; -1: current (0)
};

/// What a successful trace_on_gpu measured.
struct GpuTraceResult {
    std::string device_name;
    double scene_upload_ms = 0;  ///< NODE + TRIS (+ BVH2 for kBvh2) to the device
    double rays_upload_ms = 0;
    double kernel_ms = 0;        ///< median over `repeat` runs of the kernel launches alone
                                 ///< (TraceOptions::kernel_ms: no allocation, memset or copy)
    double kernel_ms_min = 0;
    double hits_download_ms = 0;
    double mrays_per_s = 0;      ///< rays / median kernel time
    uint64_t rays = 0, hits = 0;
    uint64_t nodes_visited = 0, triangles_tested = 0;
    uint64_t invalid_rays = 0, stack_overflows = 0, bad_indices = 0;
    uint64_t node_bytes = 0;     ///< bytes of the traversed node array (NODE or BVH2)
    uint64_t triangle_bytes = 0; ///< bytes of TRIS
};

/// Why the GPU path can or cannot run (gpu_status).
enum class GpuStatus : uint32_t {
    kReady = 0,     ///< a device is present and the kernels load on it
    kNoDevice = 1,  ///< no CUDA device (or no CUDA driver installed at all)
    kNoCuda = 2,    ///< this build has no CUDA (no nvcc at configure time, or CWBVH_CUDA=OFF)
    kUnusable = 3,  ///< a device is present but the kernels cannot run on it: driver too old
                    ///< for the runtime, no kernel image for its architecture, device busy
                    ///< or prohibited, or another CUDA error
};

/// The GPU path's status, with a one-line reason in `why` (cleared when kReady).
/// Never crashes. Benchmarks skip only on kNoDevice / kNoCuda and fail on kUnusable.
GpuStatus gpu_status(std::string& why);

/// gpu_status(why) == GpuStatus::kReady.
bool gpu_available(std::string& why);

/// Uploads the scene, the rays, traces, downloads the hits (n records into hits).
/// kDeviceError (no device, driver, CUDA error with file:line) or kInvalidArgument
/// (no BVH2 for GpuKernel::kBvh2) on failure.
Expected<GpuTraceResult> trace_on_gpu(const File& file, const Ray* rays, Hit* hits, size_t n,
                                      const GpuTraceOptions& options);

/// Same; a two-level file (format 1.2) runs the two-level kernel (trace_two_level,
/// GpuKernel::kCwbvh only) and fills `instances` (n INST indices, kInvalidIndex for a
/// miss) when it is not null. For a single-level file `instances`, if given, is
/// filled with kInvalidIndex. (The overload above traces two-level files too,
/// without their instance ids.)
Expected<GpuTraceResult> trace_on_gpu(const File& file, const Ray* rays, Hit* hits, uint32_t* instances, size_t n,
                                      const GpuTraceOptions& options);

inline Expected<GpuTraceResult> trace_on_gpu(const File& file, const Ray* rays, Hit* hits, size_t n, bool any,
                                   GpuKernel kind) {
    GpuTraceOptions o;
    o.any = any;
    o.kernel = kind;
    return trace_on_gpu(file, rays, hits, n, o);
}

}  // namespace cwbvh
