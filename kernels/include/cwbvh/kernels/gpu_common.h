// Device-side pieces shared by the GPU traversal kernels (include only from .cu
// files): launch parameters, the per-launch work area, record loads and warp
// reductions. The kernels themselves: traverse_gpu.h (CWBVH) and
// traverse_gpu_bvh2.h (the BVH2 baseline).
//
// Volta+ independent thread scheduling: every warp vote/shuffle uses the full mask
// and sits at a point all 32 lanes reach (loops in the kernels are warp-uniform:
// lanes that have nothing to do run the iteration as a no-op), so no lane reads a
// value another lane has not yet produced. cwbvh-facts 1.9 item 8.
#pragma once

#if !defined(__CUDACC__) && !defined(CWBVH_WARP_EMULATION)  // tests/model/kernel_emulation.h
#error "cwbvh/kernels/gpu_common.h is device code: include it from .cu files only"
#endif

#include <cstdint>
#include <cstring>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/gpu_stack.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"

namespace cwbvh {
namespace gpu {

inline constexpr unsigned kFullMask = 0xFFFFFFFFu;
inline constexpr int kWarpSize = 32;
/// Rays per launch: a 32-bit ray counter that never wraps (each warp may overshoot
/// the end by 32 once per fetch); trace() splits larger arrays.
inline constexpr uint64_t kMaxRaysPerLaunch = uint64_t(1) << 31;

/// Per-launch device work area: the persistent-thread ray counter and totals.
struct WorkArea {
    unsigned int next_ray;
    unsigned int pad;
    unsigned long long nodes;
    unsigned long long triangles;
    unsigned long long invalid;
    unsigned long long overflows;
    unsigned long long bad_indices;
};

struct LaunchParams {
    const CwbvhNode* nodes;
    const Bvh2Node* bvh2;
    const TriangleRecord* tris;
    uint32_t node_count;
    uint32_t tri_count;
    const Ray* rays;
    Hit* hits;
    TraceStatus* status;  // may be null
    uint32_t ray_count;
    WorkArea* work;
    NodeScale node_scale;  ///< the CWBVH kernel's fast node test (DeviceScene::node_scale)
    /// The CWBVH kernel's triangle postponing threshold (should_postpone; TraceOptions).
    uint32_t postpone_percent = kPostponePercent;
};

// ---------------------------------------------------------------------------
// Loads: read-only path, 16 bytes at a time (cudaMalloc'd arrays of 80/64/32-byte
// records are 16-byte aligned); 40-byte triangle records are only 8-byte
// aligned, so they take 8 bytes at a time.
// ---------------------------------------------------------------------------

/// Five 8-byte loads: a record is 40 bytes and record i starts at 40 * i, a
/// multiple of 8 but not of 16 (spec 3.2: the trade-off for 40 instead of 48 bytes).
__device__ __forceinline__ TriangleRecord load_triangle(const TriangleRecord* p) {
    static_assert(sizeof(TriangleRecord) == 5 * sizeof(float2));
    const float2* q = reinterpret_cast<const float2*>(p);
    float2 v[5];
    CWBVH_UNROLL
    for (int i = 0; i < 5; ++i) v[i] = __ldg(q + i);
    TriangleRecord t;
    memcpy(&t, v, sizeof(t));
    return t;
}

__device__ __forceinline__ Ray load_ray(const Ray* p) {
    const float4* q = reinterpret_cast<const float4*>(p);
    const float4 a = __ldg(q), b = __ldg(q + 1);
    return Ray{{a.x, a.y, a.z}, a.w, {b.x, b.y, b.z}, b.w};
}

/// The stored triangle id of a record alone (one 4-byte load).
__device__ __forceinline__ uint32_t load_triangle_prim(const TriangleRecord* p) { return __ldg(&p->prim); }

__device__ __forceinline__ void store_hit(Hit* p, const Hit& h) {
    *reinterpret_cast<float4*>(p) = make_float4(h.t, h.u, h.v, __uint_as_float(h.prim));
}

__device__ __forceinline__ unsigned lanemask_lt(unsigned lane) { return (1u << lane) - 1u; }

/// Warp-sum of a per-lane counter, added once per warp to a global total.
__device__ __forceinline__ void warp_add(unsigned long long* total, uint32_t value, unsigned lane) {
    unsigned long long v = value;
    CWBVH_UNROLL
    for (int off = 16; off > 0; off >>= 1) v += __shfl_down_sync(kFullMask, v, off);
    if (lane == 0 && v != 0) atomicAdd(total, v);
}

}  // namespace gpu
}  // namespace cwbvh
