// The CWBVH GPU kernel body (device code; include only from .cu files).
//
// WHICH IS WHICH:
//   traverse.h          - the per-ray CWBVH loop (CPU reference; also compiles for
//                         the device).
//   traverse_gpu.h      - THIS FILE: the warp-level CWBVH kernel body. It cannot reuse
//                         traverse.h's loop because dynamic ray fetch must interrupt a
//                         ray mid-traversal (its node group, triangle group, stack and
//                         tmax live across refills) and postponing needs warp votes at
//                         warp-uniform points. It reuses everything below the loop:
//                         make_node_ray/intersect_node (node_intersect.h),
//                         TriangleIntersector (triangle_intersect.h), StackEntry and the
//                         group encoding (traverse.h), so the per-ray step is exactly
//                         traverse.h's step (same child order, same triangle order
//                         within a group, same status codes).
//   traverse_gpu_bvh2.h - the BVH2 baseline kernel.
//   gpu_common.h        - launch parameters, loads, warp reductions.
#pragma once

#if !defined(__CUDACC__)
#error "cwbvh/traverse_gpu.h is device code: include it from .cu files only"
#endif

#include <cstdint>

#include "cwbvh/format.h"
#include "cwbvh/gpu_common.h"
#include "cwbvh/gpu_stack.h"
#include "cwbvh/node_intersect.h"
#include "cwbvh/ray.h"
#include "cwbvh/traverse.h"
#include "cwbvh/triangle_intersect.h"

namespace cwbvh {
namespace gpu {

/// Warps per block of the CWBVH kernel: 4 warps x 12 entries x 8 B x 32 lanes =
/// 12 KiB of shared stack per block.
inline constexpr int kCwbvhWarpsPerBlock = 4;
inline constexpr int kCwbvhBlockThreads = kCwbvhWarpsPerBlock * kWarpSize;

// ---------------------------------------------------------------------------
// CWBVH kernel body
// ---------------------------------------------------------------------------

/// Called by every thread of the block; blockDim.x == kCwbvhBlockThreads.
template <TriangleTest kTest, HitMode kMode>
__device__ __forceinline__ void trace_cwbvh_persistent(const LaunchParams& p, PackedEntry* warp_stack_base) {
    const unsigned lane = threadIdx.x & (kWarpSize - 1);
    GpuStack stack(warp_stack_base + lane, kWarpSize);

    // Per-lane ray state; `active` = the lane holds a ray in flight.
    bool active = false;
    uint32_t ray_id = 0;
    Ray ray{};
    NodeRay nray{};
    TriangleIntersector<kTest> tri_test(ray);
    float tmin = 0.0f, tmax = 0.0f;
    Hit hit = make_miss();
    StackEntry node_group{0u, 0u}, tri_group{0u, 0u};
    uint32_t n_nodes = 0, n_tris = 0, n_invalid = 0, n_overflow = 0, n_bad = 0;
    bool exhausted = false;  // warp-uniform: the global ray counter ran past the end

    auto finish = [&](TraceStatus status) {
        store_hit(p.hits + ray_id, hit);
        if (p.status) p.status[ray_id] = status;
        n_overflow += status == TraceStatus::kStackOverflow;
        n_bad += status == TraceStatus::kBadIndex;
        active = false;
        node_group = StackEntry{0u, 0u};
        tri_group = StackEntry{0u, 0u};
        stack.clear();
    };

    for (;;) {
        // ---- Refill idle lanes: one atomicAdd per warp, base broadcast by shuffle.
        const unsigned idle = __ballot_sync(kFullMask, !active);
        if (idle != 0 && !exhausted) {
            const unsigned want = __popc(idle);
            unsigned base = 0;
            if (lane == 0) base = atomicAdd(&p.work->next_ray, want);
            base = __shfl_sync(kFullMask, base, 0);
            if (base + want >= p.ray_count) exhausted = true;  // no overflow: ray_count <= 2^31
            if (!active) {
                const uint32_t id = base + __popc(idle & lanemask_lt(lane));
                if (id < p.ray_count) {
                    ray_id = id;
                    ray = load_ray(p.rays + id);
                    hit = make_miss();
                    if (!ray_is_traceable(ray) || p.node_count == 0) {
                        ++n_invalid;
                        store_hit(p.hits + id, hit);
                        if (p.status) p.status[id] = TraceStatus::kInvalidRay;
                    } else {
                        nray = make_node_ray(ray);
                        tri_test = TriangleIntersector<kTest>(ray);
                        tmin = ray.tmin;
                        tmax = ray.tmax;
                        node_group = StackEntry{0u, 0x80000000u};  // the root, as in traverse.h
                        tri_group = StackEntry{0u, 0u};
                        stack.clear();
                        active = true;
                    }
                }
            }
        }
        if (__ballot_sync(kFullMask, active) == 0) {
            if (exhausted) break;
            continue;  // every fetched ray was invalid: fetch again
        }

        // ---- Traversal steps (warp-uniform loop) until too much work is lost.
        int lost = 0;
        for (;;) {
            if (active) {
                if (node_group.hits > 0x00FFFFFFu) {
                    const int bit = highest_bit(node_group.hits);
                    const uint32_t base = node_group.base;
                    const uint32_t imask = node_group.hits & 0xFFu;
                    node_group.hits &= ~(1u << bit);
                    const uint32_t slot = (uint32_t(bit) - 24u) ^ nray.octinv;
                    const uint32_t index = base + uint32_t(__popc(imask & ((1u << slot) - 1u)));
                    if (node_group.hits > 0x00FFFFFFu && !stack.push(node_group)) {
                        finish(TraceStatus::kStackOverflow);
                    } else if (index >= p.node_count) {
                        finish(TraceStatus::kBadIndex);
                    } else {
                        const CwbvhNode node = load_node(p.nodes + index);
                        ++n_nodes;
                        const uint32_t hitmask = intersect_node(node, nray, tmin, tmax);
                        node_group = StackEntry{node.child_base, (hitmask & 0xFF000000u) | node.imask};
                        tri_group = StackEntry{node.tri_base, hitmask & 0x00FFFFFFu};
                    }
                } else {
                    tri_group = node_group;
                    node_group = StackEntry{0u, 0u};
                }
            }

            // Triangle phase: one triangle per lane per round; minority lanes postpone.
            const int active_lanes = __popc(__ballot_sync(kFullMask, active));
            for (;;) {
                const bool wants = active && tri_group.hits != 0;
                const unsigned wanting = __ballot_sync(kFullMask, wants);
                if (wanting == 0) break;
                if (wants) {
                    if (should_postpone(__popc(wanting), active_lanes, node_group.hits > 0x00FFFFFFu)) {
                        if (!stack.push(tri_group)) {
                            finish(TraceStatus::kStackOverflow);
                        } else {
                            tri_group.hits = 0;
                        }
                    } else {
                        const int bit = highest_bit(tri_group.hits);
                        tri_group.hits &= ~(1u << bit);
                        const uint32_t ti = tri_group.base + uint32_t(bit);
                        if (ti >= p.tri_count) {
                            finish(TraceStatus::kBadIndex);
                        } else {
                            const TriangleRecord tri = load_triangle(p.tris + ti);
                            ++n_tris;
                            TriangleHit th;
                            if (tri_test(tri, tmin, tmax, th)) {
                                tmax = th.t;
                                hit = Hit{th.t, th.u, th.v, tri.prim};
                                if (kMode == HitMode::kAny) finish(TraceStatus::kOk);
                            }
                        }
                    }
                }
            }

            if (active && node_group.hits <= 0x00FFFFFFu) {
                if (stack.empty()) {
                    finish(TraceStatus::kOk);
                } else {
                    node_group = stack.pop();
                }
            }

            const unsigned act = __ballot_sync(kFullMask, active);
            if (act == 0) break;
            lost = update_lost_work(lost, __popc(act));
            if (!exhausted && lost >= kDynamicFetchNw) break;
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
