// The CWBVH kernel's A/B options: one struct, the base of both trace.h's TraceOptions
// and gpu_trace.h's GpuTraceOptions (which stays free of CUDA types), so that each
// option, its default and its documentation live once. Host code; no CUDA needed.
#pragma once

#include <cstdint>

#include "cwbvh/kernels/gpu_stack.h"

namespace cwbvh {

/// What trace() (and trace_on_gpu for a single-level file) may turn off in the CWBVH
/// kernel to measure what it gains (cwbvh_gpu_check times each beside the production
/// kernel; `cwbvh trace --gpu --no-defer-hits | --reference-node-test | --postpone-percent`).
/// Every setting gives the same hits, up to ties at equal t (which another culling order
/// may resolve to another triangle, as any two schedules may). No effect on trace_bvh2,
/// trace_two_level or GPUs before sm_80 (which neither defer nor take the fast test;
/// postponing applies there too).
struct CwbvhKernelOptions {
    /// The watertight test, closest and any hit: on sm_80 and newer, a hit that float
    /// arithmetic proves the closest so far is taken on rigorous bounds of its distance, and
    /// its double-precision t, u, v are computed when the ray ends (deferred hit distances).
    /// false: the kernel that computes them at every such triangle. No effect on the fast
    /// test (its distance is float already).
    bool defer_hits = true;
    /// The fast node test (node_intersect_fast.h: two child slots per instruction in half
    /// precision) for every ray it accepts on sm_80 and newer. false: the reference node
    /// arithmetic (node_intersect.h) for every ray.
    bool fast_node_test = true;
    /// Triangle postponing (Ylitie et al. 4.2): a lane pushes its triangles back when fewer
    /// than this percentage of the warp's active lanes want to test triangles in a round. 0
    /// never postpones; at most 100 (more is refused). The default is the paper's 20
    /// (kPostponePercent, gpu_stack.h; on 2026-11-25's H100 35 was slower on every ray set
    /// and 10 on diffuse rays, bench/results/gpu/2026-11-25-h100/policy-sweep.md).
    uint32_t postpone_percent = uint32_t(kPostponePercent);
};

}  // namespace cwbvh
