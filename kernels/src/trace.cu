// CWBVH and BVH2 trace kernels and their launch code (API: cwbvh/trace.h).
#include <cuda_runtime.h>

#include <algorithm>
#include <mutex>
#include <stdexcept>

#include "cwbvh/cuda_check.h"
#include "cwbvh/trace.h"
#include "cwbvh/traverse_gpu.h"

namespace cwbvh {
namespace gpu {

template <TriangleTest kTest, HitMode kMode>
__global__ void __launch_bounds__(kCwbvhBlockThreads) cwbvh_trace_kernel(LaunchParams p) {
    // [warp][entry][lane]: see gpu_stack.h for the bank-conflict argument.
    __shared__ PackedEntry s_stack[kCwbvhWarpsPerBlock][kGpuSharedStackEntries][kWarpSize];
    trace_cwbvh_persistent<kTest, kMode>(p, &s_stack[threadIdx.x / kWarpSize][0][0]);
}

template <TriangleTest kTest, HitMode kMode>
__global__ void __launch_bounds__(kBvh2BlockThreads) bvh2_trace_kernel(LaunchParams p) {
    trace_bvh2_persistent<kTest, kMode>(p);
}

}  // namespace gpu

namespace {

using KernelFn = void (*)(gpu::LaunchParams);

struct KernelEntry {
    const char* name;
    KernelFn fn;
    int block_threads;
};

// Index: structure * 4 + test * 2 + query.
const KernelEntry kKernels[8] = {
    {"cwbvh_watertight_closest", gpu::cwbvh_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest>,
     gpu::kCwbvhBlockThreads},
    {"cwbvh_watertight_any", gpu::cwbvh_trace_kernel<TriangleTest::kWatertight, HitMode::kAny>,
     gpu::kCwbvhBlockThreads},
    {"cwbvh_fast_closest", gpu::cwbvh_trace_kernel<TriangleTest::kFast, HitMode::kClosest>,
     gpu::kCwbvhBlockThreads},
    {"cwbvh_fast_any", gpu::cwbvh_trace_kernel<TriangleTest::kFast, HitMode::kAny>, gpu::kCwbvhBlockThreads},
    {"bvh2_watertight_closest", gpu::bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest>,
     gpu::kBvh2BlockThreads},
    {"bvh2_watertight_any", gpu::bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kAny>,
     gpu::kBvh2BlockThreads},
    {"bvh2_fast_closest", gpu::bvh2_trace_kernel<TriangleTest::kFast, HitMode::kClosest>,
     gpu::kBvh2BlockThreads},
    {"bvh2_fast_any", gpu::bvh2_trace_kernel<TriangleTest::kFast, HitMode::kAny>, gpu::kBvh2BlockThreads},
};

/// Persistent grid: SMs x resident blocks per SM, cached per (device, kernel).
uint32_t persistent_blocks(int device, int k) {
    constexpr int kMaxDevices = 64;
    static std::mutex mutex;
    static uint32_t cache[kMaxDevices][8] = {};
    if (device >= 0 && device < kMaxDevices) {
        std::lock_guard<std::mutex> lock(mutex);
        if (cache[device][k] != 0) return cache[device][k];
    }
    int sms = 0, per_sm = 0;
    CWBVH_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
    CWBVH_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, kKernels[k].fn,
                                                                   kKernels[k].block_threads, 0));
    const uint32_t blocks = uint32_t(std::max(1, sms * std::max(1, per_sm)));
    if (device >= 0 && device < kMaxDevices) {
        std::lock_guard<std::mutex> lock(mutex);
        cache[device][k] = blocks;
    }
    return blocks;
}

void launch(int structure, const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, size_t n, Query query,
            cudaStream_t stream, const TraceOptions& options) {
    if (scene.empty()) throw std::invalid_argument("cwbvh::trace: empty DeviceScene");
    if (structure == 1 && !scene.has_bvh2())
        throw std::invalid_argument("cwbvh::trace_bvh2: the scene has no BVH2 section (compile with --keep-sbvh)");
    if (n != 0 && (d_rays == nullptr || d_hits == nullptr))
        throw std::invalid_argument("cwbvh::trace: null ray or hit pointer");
    const int k = structure * 4 + (options.test == TriangleTest::kFast ? 2 : 0) + (query == Query::kAny ? 1 : 0);
    const KernelEntry& kernel = kKernels[k];

    int device = -1;
    CWBVH_CUDA_CHECK(cudaGetDevice(&device));
    if (device != scene.device())
        throw std::invalid_argument("cwbvh::trace: the current device is not the scene's device");

    gpu::WorkArea* work = nullptr;
    const size_t batches = n == 0 ? 0 : size_t((n - 1) / gpu::kMaxRaysPerLaunch + 1);
    const size_t work_bytes = sizeof(gpu::WorkArea) * std::max<size_t>(batches, 1);
    CWBVH_CUDA_CHECK(cudaMallocAsync(reinterpret_cast<void**>(&work), work_bytes, stream));
    uint32_t blocks_used = 0;
    try {
        CWBVH_CUDA_CHECK(cudaMemsetAsync(work, 0, work_bytes, stream));
        for (size_t b = 0; b < batches; ++b) {
            const size_t first = b * gpu::kMaxRaysPerLaunch;
            const uint32_t count = uint32_t(std::min<uint64_t>(n - first, gpu::kMaxRaysPerLaunch));
            gpu::LaunchParams p{};
            p.nodes = scene.nodes();
            p.bvh2 = scene.bvh2();
            p.tris = scene.triangles();
            p.node_count = structure == 0 ? scene.node_count() : scene.bvh2_count();
            p.tri_count = scene.triangle_count();
            p.rays = d_rays + first;
            p.hits = d_hits + first;
            p.status = options.d_status ? options.d_status + first : nullptr;
            p.ray_count = count;
            p.work = work + b;
            uint32_t blocks = options.blocks ? options.blocks : persistent_blocks(device, k);
            const uint32_t needed = (count + uint32_t(kernel.block_threads) - 1) / uint32_t(kernel.block_threads);
            blocks = std::min(blocks, needed);
            blocks_used = std::max(blocks_used, blocks);
            kernel.fn<<<blocks, kernel.block_threads, 0, stream>>>(p);
            CWBVH_CUDA_CHECK(cudaGetLastError());
        }
        if (options.stats) {
            DeviceTraceStats s;
            s.rays = n;
            s.blocks = blocks_used;
            s.threads_per_block = uint32_t(kernel.block_threads);
            for (size_t b = 0; b < std::max<size_t>(batches, 1); ++b) {
                gpu::WorkArea w{};
                CWBVH_CUDA_CHECK(cudaMemcpyAsync(&w, work + b, sizeof(w), cudaMemcpyDeviceToHost, stream));
                CWBVH_CUDA_CHECK(cudaStreamSynchronize(stream));
                s.nodes_visited += w.nodes;
                s.triangles_tested += w.triangles;
                s.invalid_rays += w.invalid;
                s.stack_overflows += w.overflows;
                s.bad_indices += w.bad_indices;
            }
            *options.stats = s;
        }
    } catch (...) {
        CWBVH_CUDA_WARN(cudaFreeAsync(work, stream));
        throw;
    }
    CWBVH_CUDA_CHECK(cudaFreeAsync(work, stream));
}

}  // namespace

void trace(const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, size_t n, Query query, cudaStream_t stream,
           const TraceOptions& options) {
    launch(0, scene, d_rays, d_hits, n, query, stream, options);
}

void trace_bvh2(const DeviceScene& scene, const Ray* d_rays, Hit* d_hits, size_t n, Query query,
                cudaStream_t stream, const TraceOptions& options) {
    launch(1, scene, d_rays, d_hits, n, query, stream, options);
}

int kernel_info(KernelInfo* out, int max) {
    int count = 0;
    for (int k = 0; k < 8 && count < max; ++k) {
        cudaFuncAttributes a{};
        CWBVH_CUDA_CHECK(cudaFuncGetAttributes(&a, kKernels[k].fn));
        out[count++] = KernelInfo{kKernels[k].name, a.numRegs, a.localSizeBytes, a.sharedSizeBytes,
                                  a.maxThreadsPerBlock, a.ptxVersion, a.binaryVersion};
    }
    return count;
}

}  // namespace cwbvh
