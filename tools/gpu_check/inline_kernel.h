// The inline query (cwbvh/kernels/query.h) as a renderer's kernel calls it: one thread
// per ray, the query compiled for the view's kind of scene (SceneLevels::kSingleLevel, or
// kTwoLevel for a two-level view), timed with CUDA events around the launch alone, as
// TraceOptions::kernel_ms times trace().
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
#include <cstdint>

#include "cwbvh/kernels/query.h"

namespace cwbvh {

/// d_hits[i] = intersect(view, d_rays[i]).hit for i < n (closest or any hit), and
/// d_instances[i] its instance where d_instances is set (a two-level view);
/// *d_not_ok (device, zeroed by the caller) counts the rays whose status is
/// kStackOverflow, kBadIndex or kWrongScene (never expected on a valid file).
/// ms: when set, the launch's elapsed milliseconds (the call then waits for it).
/// Throws CudaError (cuda_check.h) on a CUDA failure.
void run_inline_query(const SceneView& view, const Ray* d_rays, Hit* d_hits, uint32_t* d_instances, size_t n,
                      bool any, unsigned long long* d_not_ok, float* ms);

}  // namespace cwbvh
