// query_kernel.h: the inline query called from a user kernel.
#include <cuda_runtime.h>

#include "query_kernel.h"

namespace cwbvh::test {
namespace {

template <HitMode kMode, SceneLevels kLevels>
__global__ void query_kernel(SceneView view, const Ray* rays, QueryHit* out, size_t n) {
    const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (i < n) out[i] = intersect<kMode, kLevels>(view, rays[i]);
}

template <HitMode kMode>
void launch(const SceneView& view, const Ray* d_rays, QueryHit* d_out, size_t n, bool specialized) {
    const unsigned threads = 128, blocks = unsigned((n + threads - 1) / threads);
    if (!specialized)
        query_kernel<kMode, SceneLevels::kEither><<<blocks, threads>>>(view, d_rays, d_out, n);
    else if (view.two_level())
        query_kernel<kMode, SceneLevels::kTwoLevel><<<blocks, threads>>>(view, d_rays, d_out, n);
    else
        query_kernel<kMode, SceneLevels::kSingleLevel><<<blocks, threads>>>(view, d_rays, d_out, n);
}

}  // namespace

cudaError_t run_query_kernel(const SceneView& view, const Ray* d_rays, QueryHit* d_out, size_t n, HitMode mode,
                             bool specialized) {
    if (n == 0) return cudaSuccess;
    if (mode == HitMode::kAny)
        launch<HitMode::kAny>(view, d_rays, d_out, n, specialized);
    else
        launch<HitMode::kClosest>(view, d_rays, d_out, n, specialized);
    const cudaError_t e = cudaGetLastError();
    return e != cudaSuccess ? e : cudaDeviceSynchronize();
}

}  // namespace cwbvh::test
