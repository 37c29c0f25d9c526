// A lock-step SIMT warp model of the GPU kernels, on the CPU (issue 10, item 3).
//
// The developers' machines have no GPU. This model runs the kernels' own per-ray
// step code (cwbvh_lane.h for the CWBVH kernel) for 32 rays at a time and applies
// the kernels' warp-level rules with the same pure policy functions (gpu_stack.h:
// should_postpone, update_lost_work), so it answers, without a GPU, the questions
// a profiler answers on one: how many lanes are active per step, how many steps a
// ray takes, how the work splits between node and triangle phases, how often the
// stack spills, and how postponing and dynamic-fetch thresholds move all of these.
// It measures SIMT efficiency, not time: memory latency, caches and occupancy are
// outside it.
//
// CWBVH warp control, as in trace_cwbvh_persistent (traverse_gpu.h):
//   1. refill: lanes without a ray take the next rays from the global counter;
//   2. iteration: (a) node phase: every lane with a ray and node work takes one node
//      step (next_node + visit_node; a lane that popped a triangle group has none);
//      (b) triangle rounds: while any lane wants triangles, each wanting lane
//      either postpones its group (should_postpone(wanting, active, has node work))
//      or tests one triangle; (c) lanes without node work pop the next group into
//      the node or the triangle group (pop_if_idle); a lane with an empty stack ends
//      its ray, whose hit is written at the warp's next refill (all ended lanes
//      together; with defer_hits their deferred hits are finished there); (d) lost =
//      update_lost_work(lost, active); back to 1 when lost >= Nw and rays remain, else
//      next iteration.
// Warps are scheduled round-robin, one iteration each, and fetch from one shared
// counter, so a refill takes rays from wherever the counter is (as on the GPU with
// many resident warps).
//
// BVH2 kernels, over the lane steps of bvh2_lane.h (which documents the warp rules):
//   kAkl2012:  today's baseline (trace_bvh2_persistent, Aila, Karras, Laine 2012):
//              node phase while any lane without a postponed leaf can traverse, with
//              the lanes that hold a leaf traversing speculatively; leaf phase; refill
//              the done lanes when fewer than bvh2_fetch_threshold lanes are busy.
//   kWhileWhile2009: the kernel measured in issue 10 (Aila, Laine 2009 persistent
//              while-while: no speculation, a warp fetches 32 rays when all are done),
//              kept to check the model against that measurement.
//
// "Active lanes per issued instruction" (Nsight Compute's threads per instruction)
// is estimated by weighting each phase with an instruction count per step (the
// options' *_instructions fields; defaults are the SASS sizes of the steps, see
// bench/README.md) and counting the lanes that execute it.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/gpu_stack.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

enum class Bvh2Kernel : uint32_t { kAkl2012 = 0, kWhileWhile2009 = 1 };

struct WarpModelOptions {
    HitMode mode = HitMode::kClosest;
    TriangleTest test = TriangleTest::kWatertight;
    uint32_t warps = 1024;                    ///< resident warps sharing the ray counter
    bool postpone = true;                     ///< triangle postponing on/off
    /// The kernel's fast node test where a ray allows it (intersect_node_fast, with the
    /// scene's node_scale); false: intersect_node everywhere, i.e. traverse.h's node
    /// masks, so that without postponing every lane does the reference's work step for step.
    bool fast_node_test = true;
    int postpone_percent = kPostponePercent;  ///< postpone below this % of active lanes
    /// Postpone only lanes that have node work meanwhile (the rule before issue 10);
    /// false: any wanting lane postpones (the kernel's rule, gpu_stack.h).
    bool postpone_needs_node_work = kPostponeOnlyWithNodeWork;
    bool dynamic_fetch = true;                ///< refill by lost work (else: when all lanes are done)
    /// Watertight CWBVH: defer the double-precision hit distance (cwbvh_lane.h,
    /// test_triangle_deferred), as the kernel does; false: the whole test at every triangle
    /// that passes the float stages, as the kernel does with TraceOptions::defer_hits = false
    /// and before sm_80.
    bool defer_hits = true;
    int fetch_nd = kDynamicFetchNd;
    int fetch_nw = kDynamicFetchNw;
    int shared_stack_entries = kGpuSharedStackEntries;  ///< entries below this depth are "shared"
    Bvh2Kernel bvh2_kernel = Bvh2Kernel::kAkl2012;
    int bvh2_fetch_threshold = 20;  ///< kBvh2DynamicFetchThreshold (bvh2_lane.h)
    // Instruction weights of the phases (warp instructions issued per step) for the
    // estimates of issued instructions and of active lanes per issued instruction.
    // node: the SASS size of one CWBVH node step (bench/gpu/step_sizes.sh, sm_90,
    // straight-line code). tri: calibrated so that the model reproduces the 14.3
    // active lanes per instruction Nsight Compute measured for the CWBVH kernel on
    // sponza_dabrovic (inside view, diffuse bounce 1, H100); 92 lies between the
    // probes' fast test (128 incl. ray set-up) and the watertight float path. With
    // these weights the BVH2 2009 model predicts 9.4 for the 9.5 measured there.
    // Control code (votes, pops) is left out: a few instructions per iteration.
    // These defaults describe the kernel as measured (issue 10's H100 run); the node
    // step of today's kernel is 188 by the same probe on its common path
    // (intersect_node_fast in half pairs since 2026-11-27, 221 in float before; 373 with
    // the reference arithmetic, which rays the fast test does not accept take):
    // `cwbvh model --node-instructions 188`.
    double node_instructions = 440;      ///< one CWBVH node step (load, 8 box tests, hit mask)
    double tri_instructions = 92;        ///< one triangle test (load, test)
    double control_instructions = 0;     ///< per iteration, all 32 lanes
    double refill_instructions = 150;    ///< per refill: vote, atomic, ray load and set-up (probe_ray_setup 112)
    double bvh2_node_instructions = 240; ///< one BVH2 node step (64-byte load, 2 robust box tests)
};

struct WarpModelStats {
    uint64_t rays = 0, hits = 0;
    uint64_t lane_node_steps = 0;   ///< nodes visited, summed over lanes
    uint64_t lane_fast_node_steps = 0;  ///< of which with intersect_node_fast (fast_node_test)
    uint64_t lane_tri_tests = 0;    ///< triangles tested, summed over lanes
    uint64_t warp_node_steps = 0;   ///< warp-level node phases issued (>= 1 lane active)
    uint64_t warp_tri_steps = 0;    ///< warp-level triangle rounds issued
    uint64_t warp_iterations = 0;   ///< outer iterations (CWBVH) / node+leaf loop trips (BVH2)
    uint64_t refills = 0;           ///< warp refill events
    uint64_t postponed = 0;         ///< triangle groups pushed by postponing
    uint64_t spilled_pushes = 0;    ///< pushes at depth >= shared_stack_entries
    uint64_t max_stack = 0;         ///< deepest stack seen
    /// The ray with the most node visits plus triangle tests (CWBVH model): a launch lasts as
    /// long as its slowest warp, and one ray's steps are serial, so a single ray of thousands
    /// of nodes sets the kernel time while the means above barely move (the 2026-11-28 H200
    /// run: 1,242 nodes for one dragon diffuse ray, 15.4 on average). worst_ray_id: its index
    /// in the ray array (0 when no ray ran).
    uint64_t worst_ray_id = 0;
    uint32_t worst_ray_nodes = 0, worst_ray_tris = 0;
    uint64_t stack_overflows = 0, bad_indices = 0, invalid_rays = 0;
    // The watertight test's double-precision path, and deferred hits (defer_hits:
    // cwbvh_lane.h, test_triangle_deferred):
    uint64_t lane_deferred_hits = 0;  ///< hits taken on float bounds, t, u, v deferred
    uint64_t lane_whole_tests = 0;    ///< triangle tests that reached the double-precision path
    uint64_t warp_whole_rounds = 0;   ///< triangle rounds in which some lane reached it
    uint64_t lane_prev_finished = 0;  ///< deferred hits finished inside a round (float undecided)
    uint64_t warp_finalize_steps = 0; ///< refills that finished deferred hits (>= 1 lane)
    uint64_t lane_finalized = 0;      ///< deferred hits finished at refill time
    /// A deferred hit the whole test does not confirm bit for bit (t, u, v), in a round or at
    /// a refill: a bug (the tests and cwbvh_fuzz_trace hold it at 0).
    uint64_t finalize_failures = 0;
    uint64_t active_lane_iterations = 0;  ///< sum over iterations of lanes holding a ray
    uint64_t node_lane_hist[33] = {};     ///< warp node steps by lanes active in them
    uint64_t tri_lane_hist[33] = {};      ///< warp triangle rounds by lanes active in them

    double lanes_per_node_step() const { return warp_node_steps ? double(lane_node_steps) / double(warp_node_steps) : 0; }
    double lanes_per_tri_step() const { return warp_tri_steps ? double(lane_tri_tests) / double(warp_tri_steps) : 0; }
    double lanes_per_iteration() const {
        return warp_iterations ? double(active_lane_iterations) / double(warp_iterations) : 0;
    }
    /// Share of issued node+triangle warp steps that are triangle rounds.
    double tri_step_share() const {
        const uint64_t t = warp_node_steps + warp_tri_steps;
        return t ? double(warp_tri_steps) / double(t) : 0;
    }
    double steps_per_ray() const {
        return rays ? double(warp_node_steps + warp_tri_steps) * 32.0 / double(rays) : 0;
    }
    double estimated_lanes_per_instruction = 0;  ///< weighted by the options' instruction counts
    double estimated_instructions = 0;           ///< warp instructions issued, same weights
    double instructions_per_ray() const { return rays ? estimated_instructions / double(rays) : 0; }
};

/// Runs the CWBVH kernel's lane code and warp control over `rays`; writes the hits
/// (identical to the kernel's, and to the CPU reference's up to ties at equal t).
WarpModelStats model_cwbvh_warps(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris,
                                 size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                                 const WarpModelOptions& options = {});

/// A BVH2 kernel (options.bvh2_kernel) over a BVH2 or BV2L section; hits equal
/// the CPU BVH2 traversal's bit for bit.
WarpModelStats model_bvh2_warps(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris,
                                     size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                                     const WarpModelOptions& options = {});

}  // namespace cwbvh
