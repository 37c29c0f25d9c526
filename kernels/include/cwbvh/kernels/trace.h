// GPU trace API over a DeviceScene. Rays and hits are device pointers (Ray, Hit
// of ray.h; same records as the ray/hit files). Asynchronous on `stream` unless
// TraceOptions::stats is set. Throws cwbvh::CudaError (cuda_check.h) on any CUDA
// failure, std::invalid_argument on misuse (e.g. trace_bvh2 without BVH2).
//
// Kernels (kernels/src/trace.cu, loop in kernels/include/cwbvh/kernels/traverse_gpu.h):
//   trace      - CWBVH, Ylitie et al. 2017: persistent warps, dynamic ray fetch,
//                shared-memory stack with local spill, triangle postponing.
//   trace_bvh2 - baseline: Aila, Laine and Karras 2012 (kepler_dynamic_fetch:
//                speculative while-while, dynamic fetch) over the BV2L section
//                (cwbvhc --keep-sbvh) or a legacy BVH2 section; 64-byte nodes.
//   trace_two_level - a two-level (instanced) file: the same CWBVH loop entering
//                each instance in its object space (trace_two_level.cu).
// Both use the same triangle test and produce the same Hit records as the CPU
// reference (cpu_trace.h); see tools/gpu_check for the comparison.
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
#include <cstdint>

#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/kernels/kernel_options.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

enum class Query : uint32_t { kClosest = 0, kAny = 1 };

/// Totals over one trace call (filled when TraceOptions::stats is set).
struct DeviceTraceStats {
    uint64_t rays = 0;
    uint64_t nodes_visited = 0;     ///< wide or binary nodes whose children were tested
    uint64_t triangles_tested = 0;
    uint64_t invalid_rays = 0;      ///< not traceable: answered with a miss
    uint64_t stack_overflows = 0;   ///< hit not trustworthy for these rays
    uint64_t bad_indices = 0;       ///< corrupt tree
    uint32_t blocks = 0;            ///< grid size of the persistent launch
    uint32_t threads_per_block = 0;
};

/// The CWBVH kernel's A/B options (defer_hits, fast_node_test, postpone_percent) come from
/// CwbvhKernelOptions (kernel_options.h); they apply to trace() only.
struct TraceOptions : CwbvhKernelOptions {
    TriangleTest test = TriangleTest::kWatertight;
    /// Optional device array of n statuses (TraceStatus per ray).
    TraceStatus* d_status = nullptr;
    /// Optional host pointer: when set, trace() synchronises `stream` and fills it.
    DeviceTraceStats* stats = nullptr;
    /// Persistent grid size; 0: SM count x resident blocks per SM (occupancy API).
    uint32_t blocks = 0;
    /// Optional host pointer: when set, trace() records CUDA events around the kernel
    /// launches only (not the work-area allocation, memset, statistics copy or free),
    /// synchronises `stream` and writes the elapsed milliseconds. Benchmarks use this:
    /// events around the whole call pull every ratio toward 1 on short launches.
    float* kernel_ms = nullptr;
};

/// CWBVH kernel. d_rays, d_hits: n records each, on scene.device(). A two-level
/// scene (DeviceScene::has_two_level()) is refused (std::invalid_argument): trace_two_level.
void trace(const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, size_t n, Query query,
           cudaStream_t stream = nullptr, const TraceOptions& options = {});

/// BVH2 baseline kernel (needs a scene uploaded with its BVH2 section).
void trace_bvh2(const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, size_t n, Query query,
                cudaStream_t stream = nullptr, const TraceOptions& options = {});

/// Two-level kernel (kernels/src/trace_two_level.cu) over a scene uploaded with its
/// top level (DeviceScene::has_two_level()). d_instances: optional device array of n
/// INST indices (kInvalidIndex for a miss); d_hits as trace(), prim the global
/// stored id. Same Hit records as trace_two_level_cpu (cpu_trace.h), bit for bit.
void trace_two_level(const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, uint32_t* d_instances, size_t n,
                     Query query, cudaStream_t stream = nullptr, const TraceOptions& options = {});

/// Static kernel properties, from cudaFuncGetAttributes (for reports).
struct KernelInfo {
    const char* name;
    int registers;
    size_t local_bytes;
    size_t shared_bytes;
    int max_threads_per_block;
    int ptx_version;
    int binary_version;
};
/// Fills up to `max` entries (one per kernel instantiation); returns the count.
/// Throws CudaError when no kernel image fits the device.
int kernel_info(KernelInfo* out, int max);

}  // namespace cwbvh
