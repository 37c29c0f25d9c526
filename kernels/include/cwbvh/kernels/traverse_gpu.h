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

#if !defined(__CUDACC__) && !defined(CWBVH_WARP_EMULATION)  // tests/model/kernel_emulation.h
#error "cwbvh/kernels/traverse_gpu.h is device code: include it from .cu files only"
#endif

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/cwbvh_lane.h"
#include "cwbvh/kernels/gpu_common.h"
#include "cwbvh/kernels/gpu_stack.h"
#include "cwbvh/kernels/node_intersect.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {
namespace gpu {

/// Warps per block of the CWBVH kernel: 4 warps x 12 entries x 8 B x 32 lanes =
/// 12 KiB of shared stack per block.
inline constexpr int kCwbvhWarpsPerBlock = 4;
inline constexpr int kCwbvhBlockThreads = kCwbvhWarpsPerBlock * kWarpSize;
/// __launch_bounds__ minimum blocks per SM: 6 x 128 threads caps the kernel at
/// 65536 / 768 = 85 -> 80 registers per thread (37.5 % occupancy on sm_90), where it
/// needs no spills (bench/results/ptxas-sm_90.txt). Issue 10's H100 run: this cap
/// was 5-13 % faster than 128 registers, 8 blocks (64 registers, spills) -5 to +16 %.
/// CMake -DCWBVH_CWBVH_MIN_BLOCKS=N (scripts/gpu-check.sh: MIN_BLOCKS=N) tries others.
#ifndef CWBVH_CWBVH_MIN_BLOCKS
#define CWBVH_CWBVH_MIN_BLOCKS 6
#endif
inline constexpr int kCwbvhMinBlocksPerSm = CWBVH_CWBVH_MIN_BLOCKS;

/// Deferred hit distances (issue 18; cwbvh_lane.h, test_triangle_deferred): the
/// watertight kernels take a hit float proves the closest so far without the double-
/// precision distance and finish it when the warp refills. The kernel body's kDeferAsked
/// = false runs the whole test at every triangle past the float stages, as before the
/// deferral (TraceOptions::defer_hits = false; cwbvh_gpu_check times both in one run).
/// Not before sm_80: the deferral's shared memory (the lane's tlo, ray id and nine per-ray
/// constants, 5.6 KiB a block; 19 KiB in all, 20 KiB in the statistics variants) would leave a
/// Turing SM (64 KiB) 3 resident blocks instead of 4. sm_80 and sm_90 (164 and 228 KiB) keep 6;
/// sm_86/89 (100 KiB) run the sm_80 code with 5 (the statistics variants with 4). The answers
/// are the same either way.
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
inline constexpr bool kDeferHits = false;
#else
inline constexpr bool kDeferHits = true;
#endif

// ---------------------------------------------------------------------------
// CWBVH kernel body
// ---------------------------------------------------------------------------

/// The watertight test's per-ray rows (WatertightRay: dir, mx, my) to and from shared
/// memory, one float per lane in each of nine rows (no bank conflicts). The fast test's
/// constants stay in registers.
template <TriangleTest kTest>
__device__ __forceinline__ void save_rows(const CwbvhLane<kTest>& l, float (*s)[kCwbvhBlockThreads]) {
    if constexpr (kTest == TriangleTest::kWatertight) {
        for (int a = 0; a < 3; ++a) {
            s[a][threadIdx.x] = l.tri_test.w.dir[a];
            s[3 + a][threadIdx.x] = l.tri_test.w.mx[a];
            s[6 + a][threadIdx.x] = l.tri_test.w.my[a];
        }
    }
}
template <TriangleTest kTest>
__device__ __forceinline__ void load_rows(CwbvhLane<kTest>& l, float (*s)[kCwbvhBlockThreads]) {
    if constexpr (kTest == TriangleTest::kWatertight) {
        for (int a = 0; a < 3; ++a) {
            l.tri_test.w.dir[a] = s[a][threadIdx.x];
            l.tri_test.w.mx[a] = s[3 + a][threadIdx.x];
            l.tri_test.w.my[a] = s[6 + a][threadIdx.x];
        }
    }
}

/// Rare per-ray outcomes go straight to the global totals (no per-lane counters).
__device__ __forceinline__ void count_rare(unsigned long long* total) { atomicAdd(total, 1ull); }

/// Called by every thread of the block; blockDim.x == kCwbvhBlockThreads.
/// kCount: also count nodes and triangles per lane (the statistics variant; the
/// production kernel carries no counters). Warp-level control, identical in the
/// CPU warp model (warp_model.h, which documents it step by step; the tests run this
/// body on the CPU against it: tests/model/kernel_emulation_test.cpp):
///   refill:  lanes without a ray take the next ones from the global counter (one
///            atomicAdd per warp);
///   iterate: every active lane with node work takes one node step; then triangle
///            rounds, one triangle per wanting lane per round, where a lane postpones
///            its group when should_postpone(wanting, active, has node work); then
///            lanes without node work pop the next group (pop_if_idle: into the node
///            or the triangle group); then update_lost_work, and the warp goes back
///            to refill when the lost work reaches kDynamicFetchNw (rays remaining).
/// kDeferAsked: deferred hit distances where the test and the architecture have them
/// (kDeferHits above); false: the kernel without them, the same hits (A/B runs).
template <TriangleTest kTest, HitMode kMode, bool kCount, bool kDeferAsked = true>
__device__ __forceinline__ void trace_cwbvh_persistent(const LaunchParams& p, PackedEntry* warp_stack_base) {
    const unsigned lane = threadIdx.x & (kWarpSize - 1);
    // The fast test defers nothing (its hit distance is float already).
    constexpr bool kDefer = kDeferAsked && kDeferHits && kTest == TriangleTest::kWatertight;
    static_assert(GpuStack::kStride == kWarpSize, "the shared stack layout is [warp][entry][lane]");
    PackedEntry spill[kGpuLocalStackEntries];  // local memory, apart from the stack object (gpu_stack.h)
    GpuStack stack(warp_stack_base + lane, spill);

    // The ray id is read only when the hit is written: in shared memory where the deferral
    // needs the register (kDefer), else in a register.
    __shared__ uint32_t s_ray_id[kCwbvhBlockThreads];
    uint32_t ray_id_reg = 0;
    CwbvhLane<kTest> l(Ray{{0.0f, 0.0f, 0.0f}, 0.0f, {1.0f, 1.0f, 1.0f}, 0.0f});
    // Statistics variant: the per-lane counters live in shared memory, not in two
    // registers the production variant does not have (keeps the counting variant
    // within the same 80-register budget without spills).
    __shared__ uint32_t s_counts[2][kCwbvhBlockThreads];
    if (kCount) s_counts[0][threadIdx.x] = s_counts[1][threadIdx.x] = 0;
    // u, v of the closest hit so far, written at each hit the whole test found: the ray's
    // Hit is then tmax, these and the triangle's id, instead of a second run of the whole
    // triangle test when the ray ends (about 200 instructions for a watertight hit; issue
    // 18). Shared memory, not two more registers (the 80-register cap); the same values
    // bit for bit, since the test that hit computed them. A deferred hit has none until
    // finalize_hit computes them at refill time.
    __shared__ float2 s_uv[kCwbvhBlockThreads];
    // The lane's tlo (cwbvh_lane.h, CwbvhLane::hit_deferred), in shared memory: a register
    // more pushed the watertight kernels past their 80 registers.
    __shared__ float s_tlo[kCwbvhBlockThreads];
    // The watertight test's per-ray rows (WatertightRay: dir, mx, my; org is the NodeRay's),
    // in shared memory: nine registers the node steps never read, loaded before each
    // triangle test (nine loads) instead of held across the loop (80-register cap).
    __shared__ float s_wt[9][kCwbvhBlockThreads];
    bool exhausted = false;  // warp-uniform: the global ray counter ran past the end

    // The lane's one state word: no ray (kIdle), tracing ray_id (kRunning), or the
    // TraceStatus of the ray that ended, whose hit is written at the warp's next refill
    // (one copy of the hit write in the code, run by all the warp's ended lanes at
    // once). One word, not an
    // `active` flag beside an `ending` code: under the 80-register cap nvcc kept the
    // flag as a byte in a shared register and copied both around the loop (issue 18).
    // A lane wants triangles only while it runs: the rounds test the state (one compare)
    // rather than a ray that ends clearing its triangle group, whose merge nvcc paid for
    // with four register copies in every round.
    constexpr uint32_t kRunning = 0xFFFFFFFFu, kIdle = 0xFFFFFFFEu;
    uint32_t state = kIdle;
    auto finish = [&](TraceStatus status) { state = uint32_t(status); };

    for (;;) {
        // ---- Write the hits of the rays that ended since the last refill, all such lanes
        // of the warp together (until issue 18's deferred writes, each iteration in which
        // some lane ended ran this block: most iterations).
        if (state < kIdle) {
            const TraceStatus status = TraceStatus(state);
            // The closest hit so far, also for a ray cut short (overflow, bad index):
            // what traverse.h returns (hit_tri is always a checked TRIS index).
            Hit h = make_miss();
            if (l.hit_tri != kNoTriangle) {
                float2 uv = s_uv[threadIdx.x];
                if constexpr (kDefer) {
                    if (l.hit_deferred(s_tlo[threadIdx.x])) {
                        load_rows(l, s_wt);
                        TriangleHit th;
                        finalize_hit(l, s_tlo[threadIdx.x], load_triangle(p.tris + l.hit_tri), th);
                        uv = make_float2(th.u, th.v);
                    }
                }
                h = Hit{l.tmax, uv.x, uv.y, load_triangle_prim(p.tris + l.hit_tri)};
            }
            const uint32_t ray_id = kDefer ? s_ray_id[threadIdx.x] : ray_id_reg;
            store_hit(p.hits + ray_id, h);
            if (p.status) p.status[ray_id] = status;
            if (status == TraceStatus::kStackOverflow) count_rare(&p.work->overflows);
            if (status == TraceStatus::kBadIndex) count_rare(&p.work->bad_indices);
            stack.clear();
            state = kIdle;
        }
        // ---- Refill idle lanes: one atomicAdd per warp, base broadcast by shuffle.
        const unsigned idle = __ballot_sync(kFullMask, state == kIdle);
        if (idle != 0 && !exhausted) {
            const unsigned want = __popc(idle);
            unsigned base = 0;
            if (lane == 0) base = atomicAdd(&p.work->next_ray, want);
            base = __shfl_sync(kFullMask, base, 0);
            if (base + want >= p.ray_count) exhausted = true;  // no overflow: ray_count <= 2^31
            if (state == kIdle) {
                const uint32_t id = base + __popc(idle & lanemask_lt(lane));
                if (id < p.ray_count) {
                    if constexpr (kDefer)
                        s_ray_id[threadIdx.x] = id;
                    else
                        ray_id_reg = id;
                    const Ray ray = load_ray(p.rays + id);
                    if (!ray_is_traceable(ray) || p.node_count == 0) {
                        store_hit(p.hits + id, make_miss());
                        if (p.status) p.status[id] = TraceStatus::kInvalidRay;
                        count_rare(&p.work->invalid);
                    } else {
                        l = CwbvhLane<kTest>(ray, p.node_scale);
                        if constexpr (kDefer) {
                            save_rows(l, s_wt);
                            s_tlo[threadIdx.x] = l.tmax;
                        }
                        stack.clear();
                        state = kRunning;
                    }
                }
            }
        }
        if (__ballot_sync(kFullMask, state == kRunning) == 0) {
            if (exhausted) break;
            continue;  // every fetched ray was invalid: fetch again
        }

        // ---- Traversal iterations (warp-uniform loop) until too much work is lost.
        int lost = 0;
        for (;;) {
            // next_node's parts inline (no status to return and switch on: issue 18).
            if (state == kRunning) {
                if (l.has_node_work()) {
                    const uint32_t index = take_next_child(l);
                    if (l.has_node_work() && !stack.push(l.node_group)) {
                        finish(TraceStatus::kStackOverflow);
                    } else if (index >= p.node_count) {
                        finish(TraceStatus::kBadIndex);
                    } else {
                        if (kCount) ++s_counts[0][threadIdx.x];
                        visit_node(l, load_node_words(p.nodes + index), p.node_scale.frame_word);
                    }
                }  // else: no node work, only the triangle group that pop_if_idle filled
            }

            // Triangle rounds: one triangle per lane per round; minority lanes postpone.
            const int active_lanes = __popc(__ballot_sync(kFullMask, state == kRunning));
            for (;;) {
                const bool wants = state == kRunning && l.wants_triangles();
                const unsigned wanting = __ballot_sync(kFullMask, wants);
                if (wanting == 0) break;
                if (wants) {
                    if (should_postpone(__popc(wanting), active_lanes, l.has_node_work(),
                                        int(p.postpone_percent))) {
                        if (!postpone_triangles(l, stack)) finish(TraceStatus::kStackOverflow);
                    } else {
                        const uint32_t ti = take_next_triangle(l);  // next_triangle, checked here
                        if (ti >= p.tri_count) {
                            finish(TraceStatus::kBadIndex);
                        } else {
                            if (kCount) ++s_counts[1][threadIdx.x];
                            TriangleHit th;
                            if constexpr (kDefer) {
                                load_rows(l, s_wt);
                                PrevHit prev_state;
                                const TriangleStep step = test_triangle_deferred(
                                    l, s_tlo[threadIdx.x], load_triangle(p.tris + ti), ti,
                                    whole_test(l, [&](uint32_t i) { return load_triangle(p.tris + i); }), th,
                                    prev_state);
                                if (step == TriangleStep::kExact || prev_state != PrevHit::kNone)
                                    s_uv[threadIdx.x] = make_float2(th.u, th.v);
                                if (kMode == HitMode::kAny && is_hit(step)) finish(TraceStatus::kOk);
                            } else if (test_triangle(l, load_triangle(p.tris + ti), ti, th)) {
                                s_uv[threadIdx.x] = make_float2(th.u, th.v);
                                if (kMode == HitMode::kAny) finish(TraceStatus::kOk);
                            }
                        }
                    }
                }
            }

            if (state == kRunning && pop_if_idle(l, stack)) state = uint32_t(TraceStatus::kOk);

            const unsigned act = __ballot_sync(kFullMask, state == kRunning);
            if (act == 0) break;
            lost = update_lost_work(lost, __popc(act));
            if (!exhausted && lost >= kDynamicFetchNw) break;
        }
    }

    if (kCount) {
        warp_add(&p.work->nodes, s_counts[0][threadIdx.x], lane);
        warp_add(&p.work->triangles, s_counts[1][threadIdx.x], lane);
    }
}

}  // namespace gpu
}  // namespace cwbvh
