// The GPU traversal stack (paper section 4.3): the first kSharedEntries entries of
// each ray's stack live in shared memory, deeper ones spill to a per-thread array
// in local memory. Host/device code, so the index logic runs on the host in the
// warp model (kernels/src/warp_model.cpp, tested in tests/model) with an ordinary
// array standing in for shared memory.
//
// Shared layout [warp][entry][lane] of 8-byte entries: a warp pushing or popping
// entry k touches 32 consecutive 8-byte words (256 contiguous bytes), which the
// hardware serves as two conflict-free 128-byte wavefronts - the same cost as any
// 64-bit shared access. (The [lane][entry] layout puts the lanes of a warp
// kSharedEntries*8 bytes apart: with 12 entries, 96 bytes = 24 banks, so lanes
// l and l+4 collide: 8-way conflicts. cwbvh-facts 1.9 item 9.) The lanes of one warp
// need not be at the same depth: the layout is conflict-free when they are, and
// no worse than a gather when they are not.
//
// Spill policy: entry index i < kSharedEntries in shared memory, else local[i -
// kSharedEntries]. The shallow entries (pushed first, popped last) stay in shared
// memory; only rays deeper than kSharedEntries entries touch local memory, which
// the L1 caches. A full stack makes push() return false (TraceStatus::kStackOverflow).
#pragma once

#include <cstdint>

#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/traverse.h"

namespace cwbvh {

/// An 8-byte-aligned stack entry so a push/pop is one 64-bit shared access.
struct alignas(8) PackedEntry {
    uint32_t base;
    uint32_t hits;
};
static_assert(sizeof(PackedEntry) == 8);

inline constexpr int kGpuSharedStackEntries = 12;  ///< per ray in shared memory (paper: 12)
inline constexpr int kGpuLocalStackEntries = 52;   ///< spill area in local memory; 64 in total
inline constexpr int kGpuStackEntries = kGpuSharedStackEntries + kGpuLocalStackEntries;

/// The spill area lives outside the stack object (`local`, the caller's array of
/// kLocalEntries): with the array as a member, the dynamic index into it made nvcc keep
/// the whole object in local memory, so every push, pop and empty() loaded the shared
/// pointer, the stride and the size from local memory and stored the size back (three
/// loads and a store per push on sm_90, issue 18). Apart, the scalars stay in registers.
template <int kSharedEntries, int kLocalEntries>
struct SharedSpillStack {
    /// Entry k of this lane is shared[k * kStride]: the lanes of a warp (32) side by side,
    /// with shared pointing at [warp][0][lane]. A constant, not a member: one register less.
    static constexpr int kStride = 32;
#if defined(__CUDA_ARCH__)
    /// On the device the shared entry 0 of this lane as a 32-bit shared-window address:
    /// a generic pointer cost two registers, and under the kernel's register cap nvcc
    /// rebuilt it (S2R of the CTA's cluster slot, then four integer ops) at every
    /// triangle round instead.
    uint32_t shared_addr;
#else
    PackedEntry* shared;
#endif
    PackedEntry* local;  ///< kLocalEntries entries of spill area (local memory on the GPU)
    int size;

    /// shared_base: this lane's entry 0; on the device it must point into shared memory
    /// (a __shared__ array: the kernels' [warp][entry][lane] blocks), since pushes and pops
    /// address it in the shared window.
    CWBVH_HD SharedSpillStack(PackedEntry* shared_base, PackedEntry* local_area)
#if defined(__CUDA_ARCH__)
        : shared_addr(uint32_t(__cvta_generic_to_shared(shared_base))), local(local_area), size(0) {}
#else
        : shared(shared_base), local(local_area), size(0) {}
#endif

    CWBVH_HD bool push(StackEntry e) {
        if (size < kSharedEntries) {
#if defined(__CUDA_ARCH__)
            asm volatile("st.shared.v2.u32 [%0], {%1, %2};" ::"r"(shared_addr + uint32_t(size * kStride * 8)),
                         "r"(e.base), "r"(e.hits));
#else
            shared[size * kStride] = PackedEntry{e.base, e.hits};
#endif
        } else if (size < kSharedEntries + kLocalEntries) {
            local[size - kSharedEntries] = PackedEntry{e.base, e.hits};
        } else {
            return false;
        }
        ++size;
        return true;
    }
    CWBVH_HD bool empty() const { return size == 0; }
    CWBVH_HD StackEntry pop() {
        --size;
        if (size < kSharedEntries) {
#if defined(__CUDA_ARCH__)
            uint32_t base, hits;
            asm volatile("ld.shared.v2.u32 {%0, %1}, [%2];"
                         : "=r"(base), "=r"(hits)
                         : "r"(shared_addr + uint32_t(size * kStride * 8)));
            return StackEntry{base, hits};
#else
            const PackedEntry p = shared[size * kStride];
            return StackEntry{p.base, p.hits};
#endif
        }
        const PackedEntry p = local[size - kSharedEntries];
        return StackEntry{p.base, p.hits};
    }
    CWBVH_HD void clear() { size = 0; }
};

using GpuStack = SharedSpillStack<kGpuSharedStackEntries, kGpuLocalStackEntries>;

// ---------------------------------------------------------------------------
// Warp-level policies, written as pure functions so the host tests can check them.
// ---------------------------------------------------------------------------

/// Dynamic ray fetch (paper 4.4): Nd = lanes allowed to idle for free, Nw = the
/// accumulated idle-lane budget that triggers a refill. After every traversal step
/// lost += (32 - active) - Nd, floored at 0 (a full warp earns no credit for later);
/// when lost >= Nw and rays remain the warp leaves the step loop and refills its
/// idle lanes in one atomicAdd.
inline constexpr int kDynamicFetchNd = 4;
inline constexpr int kDynamicFetchNw = 16;

/// nd: the free idle lanes (the kernel uses kDynamicFetchNd; the warp model varies it).
CWBVH_HD CWBVH_INLINE int update_lost_work(int lost, int active_lanes, int nd = kDynamicFetchNd) {
    const int v = lost + (32 - active_lanes) - nd;
    return v > 0 ? v : 0;
}

/// Triangle postponing (paper 4.2): a lane that wants to test triangles pushes its
/// triangle group instead when fewer than kPostponePercent % of the warp's active
/// lanes want to test triangles in this round.
///
/// kPostponeOnlyWithNodeWork = false (issue 10): the earlier rule postponed only
/// lanes that still had node work, so a lane whose node hit only leaves tested its
/// triangles alone: the CPU warp model (warp_model.h) found 42 % of the triangle
/// rounds on sponza_dabrovic's diffuse rays had one active lane, 3.5 lanes per round
/// on average and 84 % of all warp steps in triangle rounds. Postponing regardless
/// (the paper's loop: push the group whenever the warp's triangle work is a
/// minority) gives 9.1 lanes per round and 27 % fewer estimated instructions per
/// ray (bench/results/model/). A lane without node work that postpones pops its
/// group again at the end of the same iteration and retries in the next one, when
/// other lanes may want triangles too. Progress: every iteration, each active lane
/// that does not test triangles takes a node step, pops, or ends, and each ray has
/// finitely many of those; and when every active lane wants triangles, nobody
/// postpones. So a postponing lane waits at most for the other lanes' remaining
/// work, never forever.
inline constexpr int kPostponePercent = 20;
inline constexpr bool kPostponeOnlyWithNodeWork = false;

/// percent: the kernel's from its launch (TraceOptions::postpone_percent, default
/// kPostponePercent), the warp model's from its options; only_with_node_work: the
/// kernel uses the constant above, the warp model varies it.
CWBVH_HD CWBVH_INLINE bool should_postpone(int lanes_wanting_triangles, int active_lanes, bool has_node_work,
                                           int percent = kPostponePercent,
                                           bool only_with_node_work = kPostponeOnlyWithNodeWork) {
    return (has_node_work || !only_with_node_work) && 100 * lanes_wanting_triangles < percent * active_lanes;
}

}  // namespace cwbvh
