// The BVH2 baseline GPU kernel body (device code; include only from .cu files).
// See traverse_gpu.h for the CWBVH kernel and gpu_common.h for the shared pieces.
#pragma once

#if !defined(__CUDACC__)
#error "cwbvh/traverse_gpu_bvh2.h is device code: include it from .cu files only"
#endif

#include <cstdint>

#include "cwbvh/format.h"
#include "cwbvh/gpu_common.h"
#include "cwbvh/ray.h"
#include "cwbvh/traverse.h"
#include "cwbvh/traverse_bvh2.h"
#include "cwbvh/triangle_intersect.h"

namespace cwbvh {
namespace gpu {

inline constexpr int kBvh2BlockThreads = 128;
inline constexpr int kBvh2StackEntries = 64;  ///< same bound as traverse_bvh2's default

// ---------------------------------------------------------------------------
// BVH2 baseline: persistent while-while (Aila & Laine 2009)
// ---------------------------------------------------------------------------

/// One ray, the loop of traverse_bvh2.h with 16-byte node loads.
template <TriangleTest kTest, HitMode kMode>
__device__ __forceinline__ TraceStatus trace_bvh2_ray(const LaunchParams& p, const Ray& ray, Hit& hit,
                                                      uint32_t& n_nodes, uint32_t& n_tris) {
    hit = make_miss();
    const Bvh2Ray bray = make_bvh2_ray(ray);
    const TriangleIntersector<kTest> tri_test(ray);
    const float tmin = ray.tmin;
    float tmax = ray.tmax;
    constexpr int32_t kSentinel = 0x76543210;
    int32_t stack[kBvh2StackEntries];
    int sp = 0;
    int32_t node = 0;
    while (node != kSentinel) {
        while (node >= 0 && node != kSentinel) {
            if (uint32_t(node) >= p.node_count) return TraceStatus::kBadIndex;
            const float4* np = reinterpret_cast<const float4*>(p.bvh2 + node);
            const float4 a = __ldg(np), b = __ldg(np + 1), c = __ldg(np + 2);
            const int4 d = __ldg(reinterpret_cast<const int4*>(np) + 3);
            ++n_nodes;
            const float lo0[3] = {a.x, a.z, c.x}, hi0[3] = {a.y, a.w, c.y};
            const float lo1[3] = {b.x, b.z, c.z}, hi1[3] = {b.y, b.w, c.w};
            float t0 = 0.0f, t1 = 0.0f;
            const bool h0 = intersect_box_robust(bray, lo0, hi0, tmin, tmax, t0);
            const bool h1 = intersect_box_robust(bray, lo1, hi1, tmin, tmax, t1);
            if (!h0 && !h1) {
                node = sp > 0 ? stack[--sp] : kSentinel;
            } else {
                int32_t near_child = h0 ? d.x : d.y;
                int32_t far_child = d.y;
                if (h0 && h1) {
                    if (t1 < t0) {
                        near_child = d.y;
                        far_child = d.x;
                    }
                    if (sp >= kBvh2StackEntries) return TraceStatus::kStackOverflow;
                    stack[sp++] = far_child;
                }
                node = near_child;
            }
        }
        while (node < 0) {
            const uint32_t ti = uint32_t(~node);
            if (ti >= p.tri_count) return TraceStatus::kBadIndex;
            ++n_tris;
            const TriangleRecord tri = load_triangle(p.tris + ti);
            TriangleHit th;
            if (tri_test(tri, tmin, tmax, th)) {
                tmax = th.t;
                hit = Hit{th.t, th.u, th.v, tri.prim};
                if (kMode == HitMode::kAny) return TraceStatus::kOk;
            }
            node = sp > 0 ? stack[--sp] : kSentinel;
        }
    }
    return TraceStatus::kOk;
}

/// Persistent warps fetch 32 rays at a time when all their lanes are done
/// (Aila & Laine's "persistent while-while").
template <TriangleTest kTest, HitMode kMode>
__device__ __forceinline__ void trace_bvh2_persistent(const LaunchParams& p) {
    const unsigned lane = threadIdx.x & (kWarpSize - 1);
    uint32_t n_nodes = 0, n_tris = 0, n_invalid = 0, n_overflow = 0, n_bad = 0;
    for (;;) {
        unsigned base = 0;
        if (lane == 0) base = atomicAdd(&p.work->next_ray, unsigned(kWarpSize));
        base = __shfl_sync(kFullMask, base, 0);
        if (base >= p.ray_count) break;
        const uint32_t id = base + lane;
        if (id < p.ray_count) {
            const Ray ray = load_ray(p.rays + id);
            Hit hit = make_miss();
            TraceStatus status = TraceStatus::kInvalidRay;
            if (ray_is_traceable(ray) && p.node_count != 0) {
                status = trace_bvh2_ray<kTest, kMode>(p, ray, hit, n_nodes, n_tris);
            }
            n_invalid += status == TraceStatus::kInvalidRay;
            n_overflow += status == TraceStatus::kStackOverflow;
            n_bad += status == TraceStatus::kBadIndex;
            store_hit(p.hits + id, hit);
            if (p.status) p.status[id] = status;
        }
    }
    warp_add(&p.work->nodes, n_nodes, lane);
    warp_add(&p.work->triangles, n_tris, lane);
    warp_add(&p.work->invalid, n_invalid, lane);
    warp_add(&p.work->overflows, n_overflow, lane);
    warp_add(&p.work->bad_indices, n_bad, lane);
}

}  // namespace gpu
}  // namespace cwbvh
