// A kernel of the kind a renderer writes: one thread per ray, each calling the inline
// query (cwbvh/kernels/query.h) on a SceneView passed by value (query_test.cpp).
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>

#include "cwbvh/kernels/query.h"

namespace cwbvh::test {

/// out[i] = intersect<mode>(view, rays[i]) for i < n (device arrays); specialized: the
/// query compiled for the view's kind of scene alone (SceneLevels), else for either.
/// Waits for the kernel and returns its error.
cudaError_t run_query_kernel(const SceneView& view, const Ray* d_rays, QueryHit* d_out, size_t n, HitMode mode,
                             bool specialized);

}  // namespace cwbvh::test
