// The two-level CUDA kernel (issue 19) and its launch (API: trace_two_level in
// cwbvh/kernels/trace.h). Its own variant: the single-level kernels
// (kernels_cwbvh.cu, kernels_bvh2.cu) are untouched, and their ptxas report is
// identical with and without this file.
//
// Each thread runs the shared two-level loop (traverse_two_level.h: the CPU
// reference's code, so the GPU's hits are the CPU's bit for bit: the same node and
// watertight triangle tests, the same transform.h fma order) with the kernel's
// stack (gpu_stack.h: 12 entries per ray in shared memory, the rest in local
// memory). Persistent warps fetch 32 rays per atomicAdd; a warp fetches again when
// all its lanes are done (no dynamic fetch, no postponing: the single-level kernel's
// warp policies are the next step once a GPU measures it). The node test is the
// single-level kernel's: intersect_node_fast on sm_80 and later for the world ray and every
// object-space ray its set-up admits (scene constants over NODE and TLAS), the
// reference arithmetic otherwise.
#include <cuda_runtime.h>

#include <algorithm>
#include <stdexcept>

#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/gpu_common.h"
#include "cwbvh/kernels/gpu_stack.h"
#include "cwbvh/kernels/trace.h"
#include "cwbvh/kernels/traverse_two_level.h"
#include "batched_launch.h"

namespace cwbvh {
namespace gpu {
namespace {

/// __launch_bounds__ minimum blocks per SM. 4 caps the kernel at 128 registers: 122-128
/// and no spills on sm_90 and sm_75 with the fast node test (16 warps per SM); without
/// a cap one variant takes 141; 5 caps at 96 (20-52 B of spills in four variants), 6 at
/// 80 (100-208 B). Which is fastest waits for a GPU run (the single-level kernel's
/// 80-register cap won 5-13 % on the H100, issue 10); -DCWBVH_TWO_LEVEL_MIN_BLOCKS=N
/// tries others.
#ifndef CWBVH_TWO_LEVEL_MIN_BLOCKS
#define CWBVH_TWO_LEVEL_MIN_BLOCKS 4
#endif
inline constexpr int kTwoLevelWarpsPerBlock = 4;
inline constexpr int kTwoLevelBlockThreads = kTwoLevelWarpsPerBlock * kWarpSize;

struct TwoLevelLaunchParams {
    TwoLevelScene scene;
    const Ray* rays;
    Hit* hits;
    uint32_t* instances;  // may be null
    TraceStatus* status;  // may be null
    uint32_t ray_count;
    WorkArea* work;
};

template <TriangleTest kTest, HitMode kMode, bool kCount>
__global__ void __launch_bounds__(kTwoLevelBlockThreads, CWBVH_TWO_LEVEL_MIN_BLOCKS) two_level_trace_kernel(TwoLevelLaunchParams p) {
    __shared__ PackedEntry s_stack[kTwoLevelWarpsPerBlock][kGpuSharedStackEntries][kWarpSize];
    const unsigned lane = threadIdx.x & (kWarpSize - 1);
    PackedEntry spill[kGpuLocalStackEntries];  // local memory, apart from the stack object (gpu_stack.h)
    GpuStack stack(&s_stack[threadIdx.x / kWarpSize][0][lane], spill);
    uint32_t nodes = 0, tris = 0;
    for (;;) {
        unsigned base = 0;
        if (lane == 0) base = atomicAdd(&p.work->next_ray, unsigned(kWarpSize));
        base = __shfl_sync(kFullMask, base, 0);
        if (base >= p.ray_count) break;  // warp-uniform; no overflow: ray_count <= 2^31
        const uint32_t id = base + lane;
        if (id < p.ray_count) {
            Hit h;
            uint32_t instance;
            TraceCounters c{0, 0};
            stack.clear();
            const TraceStatus st = traverse_two_level<kTest, kMode>(p.scene, load_ray(p.rays + id), h, instance,
                                                                    stack, kCount ? &c : nullptr);
            store_hit(p.hits + id, h);
            if (p.instances) p.instances[id] = instance;
            if (p.status) p.status[id] = st;
            if (st == TraceStatus::kInvalidRay) atomicAdd(&p.work->invalid, 1ull);
            if (st == TraceStatus::kStackOverflow) atomicAdd(&p.work->overflows, 1ull);
            if (st == TraceStatus::kBadIndex) atomicAdd(&p.work->bad_indices, 1ull);
            if (kCount) {
                nodes += c.nodes;
                tris += c.triangles;
            }
        }
    }
    if (kCount) {
        warp_add(&p.work->nodes, nodes, lane);
        warp_add(&p.work->triangles, tris, lane);
    }
}

using TwoLevelKernelFn = void (*)(TwoLevelLaunchParams);

/// [test][mode][count]
TwoLevelKernelFn two_level_kernel(TriangleTest test, Query query, bool counting) {
    static const TwoLevelKernelFn k[2][2][2] = {
        {{two_level_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest, false>,
          two_level_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest, true>},
         {two_level_trace_kernel<TriangleTest::kWatertight, HitMode::kAny, false>,
          two_level_trace_kernel<TriangleTest::kWatertight, HitMode::kAny, true>}},
        {{two_level_trace_kernel<TriangleTest::kFast, HitMode::kClosest, false>,
          two_level_trace_kernel<TriangleTest::kFast, HitMode::kClosest, true>},
         {two_level_trace_kernel<TriangleTest::kFast, HitMode::kAny, false>,
          two_level_trace_kernel<TriangleTest::kFast, HitMode::kAny, true>}}};
    return k[test == TriangleTest::kFast ? 1 : 0][query == Query::kAny ? 1 : 0][counting ? 1 : 0];
}

}  // namespace
}  // namespace gpu

void trace_two_level(const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, uint32_t* d_instances, size_t n,
                     Query query, cudaStream_t stream, const TraceOptions& options) {
    if (scene.empty()) throw std::invalid_argument("cwbvh::trace_two_level: empty DeviceScene");
    if (!scene.has_two_level())
        throw std::invalid_argument("cwbvh::trace_two_level: the scene has no top level (TLAS, INST, MESH)");
    if (n != 0 && (d_rays == nullptr || d_hits == nullptr))
        throw std::invalid_argument("cwbvh::trace_two_level: null ray or hit pointer");
    int device = -1;
    CWBVH_CUDA_CHECK(cudaGetDevice(&device));
    if (device != scene.device())
        throw std::invalid_argument("cwbvh::trace_two_level: the current device is not the scene's device");
    const bool counting = options.stats != nullptr;
    const gpu::TwoLevelKernelFn fn = gpu::two_level_kernel(options.test, query, counting);

    int sms = 0, per_sm = 0;
    CWBVH_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
    CWBVH_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, fn, gpu::kTwoLevelBlockThreads, 0));
    const uint32_t persistent = uint32_t(std::max(1, sms * std::max(1, per_sm)));
    gpu::run_batched(n, stream, options, uint32_t(gpu::kTwoLevelBlockThreads),
                     [&](size_t first, uint32_t count, gpu::WorkArea* work) {
                         gpu::TwoLevelLaunchParams p{};
                         p.scene = scene.two_level();
                         p.rays = d_rays + first;
                         p.hits = d_hits + first;
                         p.instances = d_instances ? d_instances + first : nullptr;
                         p.status = options.d_status ? options.d_status + first : nullptr;
                         p.ray_count = count;
                         p.work = work;
                         const uint32_t blocks = gpu::launch_blocks(persistent, options, count,
                                                                    uint32_t(gpu::kTwoLevelBlockThreads));
                         fn<<<blocks, gpu::kTwoLevelBlockThreads, 0, stream>>>(p);
                         return blocks;
                     });
}

}  // namespace cwbvh
