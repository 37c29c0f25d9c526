// inline_kernel.h: the inline query in a one-thread-per-ray kernel, for cwbvh_gpu_check.
#include <cuda_runtime.h>

#include "cwbvh/kernels/cuda_check.h"
#include "inline_kernel.h"

namespace cwbvh {
namespace {

template <HitMode kMode, SceneLevels kLevels>
__global__ void inline_query_kernel(SceneView view, const Ray* rays, Hit* hits, uint32_t* instances, size_t n,
                                    unsigned long long* not_ok) {
    const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (i >= n) return;
    const QueryHit q = intersect<kMode, kLevels>(view, rays[i]);
    hits[i] = q.hit;
    if (instances) instances[i] = q.instance;
    // A ray the CPU reference also refuses (kInvalidRay) is compared as a miss; these are not.
    if (q.status == TraceStatus::kStackOverflow || q.status == TraceStatus::kBadIndex ||
        q.status == TraceStatus::kWrongScene)
        atomicAdd(not_ok, 1ull);
}

}  // namespace

void run_inline_query(const SceneView& view, const Ray* d_rays, Hit* d_hits, uint32_t* d_instances, size_t n,
                      bool any, unsigned long long* d_not_ok, float* ms) {
    if (n == 0) {
        if (ms) *ms = 0.0f;
        return;
    }
    constexpr unsigned kThreads = 128;
    const unsigned blocks = unsigned((n + kThreads - 1) / kThreads);
    cudaEvent_t start = nullptr, stop = nullptr;
    if (ms) {
        CWBVH_CUDA_CHECK(cudaEventCreate(&start));
        CWBVH_CUDA_CHECK(cudaEventCreate(&stop));
        CWBVH_CUDA_CHECK(cudaEventRecord(start));
    }
    const bool two = view.two_level();
    if (any && two)
        inline_query_kernel<HitMode::kAny, SceneLevels::kTwoLevel>
            <<<blocks, kThreads>>>(view, d_rays, d_hits, d_instances, n, d_not_ok);
    else if (two)
        inline_query_kernel<HitMode::kClosest, SceneLevels::kTwoLevel>
            <<<blocks, kThreads>>>(view, d_rays, d_hits, d_instances, n, d_not_ok);
    else if (any)
        inline_query_kernel<HitMode::kAny, SceneLevels::kSingleLevel>
            <<<blocks, kThreads>>>(view, d_rays, d_hits, d_instances, n, d_not_ok);
    else
        inline_query_kernel<HitMode::kClosest, SceneLevels::kSingleLevel>
            <<<blocks, kThreads>>>(view, d_rays, d_hits, d_instances, n, d_not_ok);
    CWBVH_CUDA_CHECK(cudaGetLastError());
    if (ms) {
        CWBVH_CUDA_CHECK(cudaEventRecord(stop));
        CWBVH_CUDA_CHECK(cudaEventSynchronize(stop));
        CWBVH_CUDA_CHECK(cudaEventElapsedTime(ms, start, stop));
        CWBVH_CUDA_CHECK(cudaEventDestroy(start));
        CWBVH_CUDA_CHECK(cudaEventDestroy(stop));
    }
}

}  // namespace cwbvh
