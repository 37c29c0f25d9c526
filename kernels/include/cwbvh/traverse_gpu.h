// GPU traversal loops (device code; include only from .cu files).
//
// WHICH IS WHICH:
//   traverse.h        - the per-ray CWBVH loop (CPU reference; also compiles for the
//                       device). Unchanged by this file.
//   traverse_gpu.h    - THIS FILE: the warp-level CWBVH kernel body. It cannot reuse
//                       traverse.h's loop because dynamic ray fetch must interrupt a
//                       ray mid-traversal (its node group, triangle group, stack and
//                       tmax live across refills) and postponing needs warp votes at
//                       warp-uniform points. It reuses everything below the loop:
//                       make_node_ray/intersect_node (node_intersect.h),
//                       TriangleIntersector (triangle_intersect.h), StackEntry and the
//                       group encoding (traverse.h), so the per-ray step is exactly
//                       traverse.h's step (same child order, same triangle order
//                       within a group, same status codes).
//   bvh2 part below   - the Aila-Laine while-while per-ray loop with 16-byte node
//                       loads, reusing intersect_box_robust (traverse_bvh2.h).
//
// Volta+ independent thread scheduling: every warp vote/shuffle uses the full mask
// and sits at a point all 32 lanes reach (loops below are warp-uniform: lanes that
// have nothing to do run the iteration as a no-op), so no lane reads a value another
// lane has not yet produced. The fetched ray base is broadcast with __shfl_sync (no
// shared variable, no volatile, no __syncwarp needed). cwbvh-facts 1.9 item 8.
#pragma once

#if !defined(__CUDACC__)
#error "cwbvh/traverse_gpu.h is device code: include it from .cu files only"
#endif

#include <cstdint>
#include <cstring>

#include "cwbvh/format.h"
#include "cwbvh/gpu_stack.h"
#include "cwbvh/node_intersect.h"
#include "cwbvh/ray.h"
#include "cwbvh/traverse.h"
#include "cwbvh/traverse_bvh2.h"
#include "cwbvh/triangle_intersect.h"

namespace cwbvh {
namespace gpu {

inline constexpr unsigned kFullMask = 0xFFFFFFFFu;
inline constexpr int kWarpSize = 32;
/// Warps per block of the CWBVH kernel: 4 warps x 12 entries x 8 B x 32 lanes =
/// 12 KiB of shared stack per block.
inline constexpr int kCwbvhWarpsPerBlock = 4;
inline constexpr int kCwbvhBlockThreads = kCwbvhWarpsPerBlock * kWarpSize;
inline constexpr int kBvh2BlockThreads = 128;
inline constexpr int kBvh2StackEntries = 64;  ///< same bound as traverse_bvh2's default
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
};

// ---------------------------------------------------------------------------
// Loads: read-only path, 16 bytes at a time (cudaMalloc'd arrays of 80/64/32-byte
// records are 16-byte aligned); 40-byte triangle records are only 8-byte
// aligned, so they take 8 bytes at a time.
// ---------------------------------------------------------------------------

__device__ __forceinline__ CwbvhNode load_node(const CwbvhNode* p) {
    const uint4* q = reinterpret_cast<const uint4*>(p);
    uint4 v[5];
#pragma unroll
    for (int i = 0; i < 5; ++i) v[i] = __ldg(q + i);
    CwbvhNode n;
    memcpy(&n, v, sizeof(n));
    return n;
}

/// Five 8-byte loads: a record is 40 bytes and record i starts at 40 * i, a
/// multiple of 8 but not of 16 (spec 3.2: the trade-off for 40 instead of 48 bytes).
__device__ __forceinline__ TriangleRecord load_triangle(const TriangleRecord* p) {
    static_assert(sizeof(TriangleRecord) == 5 * sizeof(float2));
    const float2* q = reinterpret_cast<const float2*>(p);
    float2 v[5];
#pragma unroll
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

__device__ __forceinline__ void store_hit(Hit* p, const Hit& h) {
    *reinterpret_cast<float4*>(p) = make_float4(h.t, h.u, h.v, __uint_as_float(h.prim));
}

__device__ __forceinline__ unsigned lanemask_lt(unsigned lane) { return (1u << lane) - 1u; }

/// Warp-sum of a per-lane counter, added once per warp to a global total.
__device__ __forceinline__ void warp_add(unsigned long long* total, uint32_t value, unsigned lane) {
    unsigned long long v = value;
#pragma unroll
    for (int off = 16; off > 0; off >>= 1) v += __shfl_down_sync(kFullMask, v, off);
    if (lane == 0 && v != 0) atomicAdd(total, v);
}

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
