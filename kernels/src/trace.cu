// CWBVH and BVH2 trace kernels and their launch code (API: cwbvh/kernels/trace.h).
#include <cuda_runtime.h>

#include <algorithm>
#include <mutex>
#include <stdexcept>

#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/gpu_common.h"
#include "cwbvh/kernels/trace.h"
#include "batched_launch.h"
#include "kernel_table.h"

namespace cwbvh {
namespace {

using gpu::KernelEntry;

/// Index: structure * 4 + test * 2 + query for the two structures' kernels, then the
/// CWBVH watertight kernels without deferred hits (kWholeTestBase + query).
constexpr int kWholeTestBase = 2 * gpu::kKernelsPerStructure;
constexpr int kKernelCount = kWholeTestBase + gpu::kWholeTestKernels;
const KernelEntry& kernel_entry(int k) {
    if (k >= kWholeTestBase) return gpu::cwbvh_whole_test_kernels()[k - kWholeTestBase];
    const KernelEntry* table = k < gpu::kKernelsPerStructure ? gpu::cwbvh_kernels() : gpu::bvh2_kernels();
    return table[k % gpu::kKernelsPerStructure];
}

/// The function a launch runs: the counting variant only when statistics are asked for.
gpu::KernelFn kernel_fn(int k, bool counting) { return counting ? kernel_entry(k).counting : kernel_entry(k).fn; }

/// Persistent grid: SMs x resident blocks per SM, cached per (device, kernel, variant).
uint32_t persistent_blocks(int device, int k, bool counting) {
    constexpr int kMaxDevices = 64;
    static std::mutex mutex;
    static uint32_t cache[kMaxDevices][2 * kKernelCount] = {};
    const gpu::KernelFn fn = kernel_fn(k, counting);
    k = 2 * k + (counting ? 1 : 0);
    if (device >= 0 && device < kMaxDevices) {
        std::lock_guard<std::mutex> lock(mutex);
        if (cache[device][k] != 0) return cache[device][k];
    }
    int sms = 0, per_sm = 0;
    CWBVH_CUDA_CHECK(cudaDeviceGetAttribute(&sms, cudaDevAttrMultiProcessorCount, device));
    CWBVH_CUDA_CHECK(cudaOccupancyMaxActiveBlocksPerMultiprocessor(&per_sm, fn,
                                                                   kernel_entry(k / 2).block_threads, 0));
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
    // NODE of a two-level scene holds the bottom levels; node 0 is one mesh's root.
    if (scene.has_two_level())
        throw std::invalid_argument("cwbvh::trace: a two-level scene (TLAS, INST, MESH): use trace_two_level");
    if (structure == 1 && !scene.has_bvh2())
        throw std::invalid_argument("cwbvh::trace_bvh2: the scene has no BVH2 section (compile with --keep-sbvh)");
    if (n != 0 && (d_rays == nullptr || d_hits == nullptr))
        throw std::invalid_argument("cwbvh::trace: null ray or hit pointer");
    if (options.postpone_percent > 100)
        throw std::invalid_argument("cwbvh::trace: CwbvhKernelOptions::postpone_percent above 100");
    const int k = structure == 0 && options.test == TriangleTest::kWatertight && !options.defer_hits
                      ? kWholeTestBase + (query == Query::kAny ? 1 : 0)
                      : structure * gpu::kKernelsPerStructure +
                            gpu::kernel_slot(options.test, query == Query::kAny ? HitMode::kAny : HitMode::kClosest);
    const KernelEntry& kernel = kernel_entry(k);
    const bool counting = options.stats != nullptr;

    int device = -1;
    CWBVH_CUDA_CHECK(cudaGetDevice(&device));
    if (device != scene.device())
        throw std::invalid_argument("cwbvh::trace: the current device is not the scene's device");

    gpu::run_batched(n, stream, options, uint32_t(kernel.block_threads),
                     [&](size_t first, uint32_t count, gpu::WorkArea* work) {
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
                         p.work = work;
                         // NodeScale{} (usable 0): no ray takes the fast node test.
                         p.node_scale = options.fast_node_test ? scene.node_scale() : NodeScale{};
                         p.postpone_percent = options.postpone_percent;
                         const uint32_t blocks =
                             gpu::launch_blocks(persistent_blocks(device, k, counting), options, count,
                                                uint32_t(kernel.block_threads));
                         kernel_fn(k, counting)<<<blocks, kernel.block_threads, 0, stream>>>(p);
                         return blocks;
                     });
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
    for (int k = 0; k < kKernelCount && count < max; ++k) {
        cudaFuncAttributes a{};
        CWBVH_CUDA_CHECK(cudaFuncGetAttributes(&a, kernel_entry(k).fn));
        out[count++] = KernelInfo{kernel_entry(k).name, a.numRegs, a.localSizeBytes, a.sharedSizeBytes,
                                  a.maxThreadsPerBlock, a.ptxVersion, a.binaryVersion};
    }
    return count;
}

}  // namespace cwbvh
