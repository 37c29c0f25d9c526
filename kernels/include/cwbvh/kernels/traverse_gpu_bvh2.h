// The BVH2 baseline GPU kernel body (device code; include only from .cu files).
// See traverse_gpu.h for the CWBVH kernel and gpu_common.h for the shared pieces.
//
// Aila, Karras and Laine 2012, "Understanding the efficiency of ray traversal on
// GPUs - Kepler and Fermi addendum" (NVIDIA tech report NVR-2012-02), kernel
// kepler_dynamic_fetch: persistent warps with dynamic ray fetch, while-while
// traversal with speculative traversal and leaf postponing (Aila & Laine 2009,
// sections 3 and 4), over 64-byte binary nodes read with four 16-byte loads. The
// per-lane work (state, one node step, one triangle step) is bvh2_lane.h; this
// file is the warp-level control that header documents, step for step.
//
// Trees: the BV2L section (leaves of 1-3 triangle records, the wide tree's SAH
// leaves, as the paper's baseline has several triangles per leaf) or the legacy
// BVH2 section (one record per leaf); the same loop reads both.
//
// Volta+ independent thread scheduling: every vote and shuffle below uses the full
// mask at a point all 32 lanes reach; the loops are warp-uniform and lanes with
// nothing to do run an iteration as a no-op (gpu_common.h).
#pragma once

#if !defined(__CUDACC__) && !defined(CWBVH_WARP_EMULATION)  // tests/model/kernel_emulation.h
#error "cwbvh/kernels/traverse_gpu_bvh2.h is device code: include it from .cu files only"
#endif

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/bvh2_lane.h"
#include "cwbvh/kernels/gpu_common.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {
namespace gpu {

inline constexpr int kBvh2BlockThreads = 128;
inline constexpr int kBvh2StackEntries = kBvh2LaneStackEntries;  ///< per-thread local memory
inline constexpr uint32_t kBvh2NoRay = 0xFFFFFFFFu;

/// The lane steps' loader on the device: a node is four 16-byte read-only loads
/// (boxes of child 0 and 1 interleaved as AKL's layout has them, then child[2]
/// and leaf_count[2]); a triangle five 8-byte loads (gpu_common.h).
/// (Host/device so that the host/device lane steps may call it; the host side,
/// never run, reads plainly.)
struct Bvh2DeviceLoad {
    __host__ __device__ __forceinline__ Bvh2Node operator()(const Bvh2Node* p) const {
#if defined(__CUDA_ARCH__)
        const float4* q = reinterpret_cast<const float4*>(p);
        const float4 a = __ldg(q), b = __ldg(q + 1), c = __ldg(q + 2);
        const int4 d = __ldg(reinterpret_cast<const int4*>(p) + 3);
        Bvh2Node n;
        n.c0_lo_x = a.x, n.c0_hi_x = a.y, n.c0_lo_y = a.z, n.c0_hi_y = a.w;
        n.c1_lo_x = b.x, n.c1_hi_x = b.y, n.c1_lo_y = b.z, n.c1_hi_y = b.w;
        n.c0_lo_z = c.x, n.c0_hi_z = c.y, n.c1_lo_z = c.z, n.c1_hi_z = c.w;
        n.child[0] = d.x, n.child[1] = d.y;
        n.leaf_count[0] = uint32_t(d.z), n.leaf_count[1] = uint32_t(d.w);
        return n;
#else
        return *p;
#endif
    }
    __host__ __device__ __forceinline__ TriangleRecord operator()(const TriangleRecord* p) const {
#if defined(__CUDA_ARCH__)
        return load_triangle(p);
#else
        return *p;
#endif
    }
};

/// Adds the number of lanes where `flag` holds to a global total (all lanes call it).
__device__ __forceinline__ void warp_count(unsigned long long* total, bool flag, unsigned lane) {
    const unsigned m = __ballot_sync(kFullMask, flag);
    if (lane == 0 && m != 0) atomicAdd(total, (unsigned long long)__popc(int(m)));
}

/// Persistent warps (Aila & Laine 2009 section 3; AKL 2012 kepler_dynamic_fetch).
/// kCount: also count node and triangle steps into WorkArea (stats runs); the
/// production kernel (kCount false) carries no counters. Status counts (invalid
/// rays, stack overflows, bad indices) are always kept, by warp votes as rays are stored.
template <TriangleTest kTest, HitMode kMode, bool kCount>
__device__ __forceinline__ void trace_bvh2_persistent(const LaunchParams& p) {
    const unsigned lane = threadIdx.x & (kWarpSize - 1);
    const Bvh2Scene scene = make_bvh2_scene(p.bvh2, p.node_count, p.tris, p.tri_count);
    const Bvh2DeviceLoad load;
    Bvh2Lane<kTest> l;  // done, no ray (registers)
    Bvh2LaneMemory m;   // stack and hit record (local memory)
    uint32_t ray_id = kBvh2NoRay;
    uint32_t n_nodes = 0, n_tris = 0;
    bool exhausted = false;  // warp-uniform: the ray pool is empty
    for (;;) {
        // 1. Store the rays that are done; count their unusual statuses (warp votes
        //    here instead of per-lane counters kept live through the whole loop).
        const bool store = bvh2_lane_done(l) && ray_id != kBvh2NoRay;
        if (store) {
            store_hit(p.hits + ray_id, bvh2_lane_hit(l, m));
            if (p.status) p.status[ray_id] = l.status;
            ray_id = kBvh2NoRay;
        }
        warp_count(&p.work->invalid, store && l.status == TraceStatus::kInvalidRay, lane);
        warp_count(&p.work->overflows, store && l.status == TraceStatus::kStackOverflow, lane);
        warp_count(&p.work->bad_indices, store && l.status == TraceStatus::kBadIndex, lane);
        // 2. Dynamic fetch: the done lanes take consecutive rays, one atomicAdd per warp.
        if (!exhausted) {
            const unsigned need = __ballot_sync(kFullMask, bvh2_lane_done(l));
            if (need != 0) {
                const int leader = __ffs(int(need)) - 1;
                unsigned base = 0;
                if (int(lane) == leader) base = atomicAdd(&p.work->next_ray, unsigned(__popc(int(need))));
                base = __shfl_sync(kFullMask, base, leader);
                if (base >= p.ray_count) {
                    exhausted = true;
                } else if (bvh2_lane_done(l)) {
                    const uint32_t id = base + uint32_t(__popc(int(need & lanemask_lt(lane))));
                    if (id < p.ray_count) {
                        ray_id = id;
                        bvh2_lane_start(l, m, load_ray(p.rays + id), scene);  // untraceable: done at once
                    }
                }
            }
        }
        if (__ballot_sync(kFullMask, !bvh2_lane_done(l)) == 0) {
            if (exhausted) break;
            continue;  // every new ray was untraceable: store them and fetch again
        }
        // 3. Trace until too few lanes are busy.
        for (;;) {
            // a. Internal nodes until every lane has a postponed leaf or cannot
            //    traverse; lanes that already hold a leaf traverse speculatively.
            while (__any_sync(kFullMask, bvh2_lane_in_nodes(l) && !bvh2_lane_has_leaf(l))) {
                if (bvh2_lane_in_nodes(l)) {
                    bvh2_lane_node_step(l, m, scene, load);
                    if constexpr (kCount) ++n_nodes;
                }
            }
            // b. Postponed leaves, one triangle per iteration.
            while (__any_sync(kFullMask, bvh2_lane_has_leaf(l))) {
                if (bvh2_lane_has_leaf(l)) {
                    bvh2_lane_triangle_step<kMode>(l, m, scene, load);
                    if constexpr (kCount) ++n_tris;
                }
            }
            // c. Refill when fewer than the threshold are busy (AKL 2012
            //    DYNAMIC_FETCH_THRESHOLD), or when none is.
            const int busy = __popc(int(__ballot_sync(kFullMask, !bvh2_lane_done(l))));
            if (busy == 0 || (!exhausted && busy < kBvh2DynamicFetchThreshold)) break;
        }
    }
    if constexpr (kCount) {
        warp_add(&p.work->nodes, n_nodes, lane);
        warp_add(&p.work->triangles, n_tris, lane);
    }
}

}  // namespace gpu
}  // namespace cwbvh
