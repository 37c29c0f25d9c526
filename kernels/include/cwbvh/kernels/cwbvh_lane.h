// The per-ray (per-lane) steps of the CWBVH GPU traversal, as host/device code.
//
// The CUDA kernel (traverse_gpu.h) and the CPU lock-step warp model (warp_model.h)
// call exactly these functions; only the warp-level control around them (votes,
// postponing decisions, ray fetch) is written twice, once with warp intrinsics and
// once as a loop over 32 simulated lanes, both following the rules documented in
// warp_model.h and both using the pure policy functions of gpu_stack.h
// (should_postpone, update_lost_work).
//
// A lane's state is kept small on purpose (issue 10: 128 registers capped the
// kernel at 25 % occupancy):
//   - the closest hit so far is the TRIS index of its triangle plus tmax (the hit
//     distance once known; while the hit is deferred, an upper bound, with the lower
//     bound tlo beside the lane: test_triangle_deferred); its u, v go to shared memory
//     at each hit the whole test found (the kernel's s_uv, the warp model's Lane) or are
//     computed when a deferred hit is finished (finalize_hit), and the primitive id is
//     read from TRIS when the ray ends (until 2026-11-26 the whole triangle test ran a
//     second time there instead: ~200 instructions per hitting ray);
//   - no Ray copy survives set-up: NodeRay and the triangle test's per-ray
//     constants are all the traversal reads;
//   - node and triangle records are loaded by the caller (the kernel through the
//     read-only cache, the model from memory) right before the step that uses them.
//
// The steps reproduce traverse.h's traversal order exactly (same child order, same
// triangle order within a group, same status codes); postponing only delays a
// triangle group, so the hit found is the same (ties at equal t aside).
#pragma once

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/node_intersect.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

/// TRIS index meaning "no hit yet".
inline constexpr uint32_t kNoTriangle = 0xFFFFFFFFu;

template <TriangleTest kTest>
struct CwbvhLane {
    NodeRay nray;
    TriangleIntersector<kTest> tri_test;
    float tmin;
    /// Current interval end: the ray's tmax, or an upper bound of the closest hit's
    /// distance (its exact distance once known). Node and triangle tests cull with it.
    /// Its partner tlo, a lower bound of that distance (test_triangle_deferred), is not a
    /// member: the kernel keeps it in shared memory (a register more spilled under the
    /// 80-register cap), the warp model beside the lane.
    float tmax;
    uint32_t hit_tri;     ///< TRIS index of the closest hit so far, kNoTriangle if none
    StackEntry node_group;
    StackEntry tri_group;

    /// Starts `ray` (which must be traceable) at the root: a node group of one
    /// (bit 31, imask 0), as in traverse.h. With the scene's NodeScale, the node
    /// steps use intersect_node_fast when the ray allows it (node_intersect_fast.h).
    /// A tmin of -0 becomes +0 (the same closed interval; the fast test needs the
    /// sign bit clear).
    CWBVH_HD CWBVH_INLINE explicit CwbvhLane(const Ray& ray, const NodeScale& scale = NodeScale{})
        : nray(make_node_ray(ray)),
          tri_test(ray),
          tmin(ray.tmin == 0.0f ? 0.0f : ray.tmin),
          tmax(ray.tmax),
          hit_tri(kNoTriangle),
          node_group{0u, 0x80000000u},
          tri_group{0u, 0u} {
        enable_fast_node_test(nray, scale, ray.dir, tmin);
    }

    CWBVH_HD CWBVH_INLINE bool has_node_work() const { return node_group.hits > 0x00FFFFFFu; }
    CWBVH_HD CWBVH_INLINE bool wants_triangles() const { return tri_group.hits != 0; }
    /// The closest hit so far is deferred (its t, u, v wait for finalize_hit), given the
    /// lane's tlo: a lower bound of the hit's distance, equal to tmax when that is exact
    /// or there is no hit (both the ray's tmax at the start), below it while deferred.
    CWBVH_HD CWBVH_INLINE bool hit_deferred(float tlo) const { return tlo < tmax; }
};

/// Result of the first half of a node step.
enum class NodeStep : uint32_t {
    kVisit = 0,      ///< `index` names the node to load and pass to visit_node
    kNoNode = 1,     ///< no node work: the lane holds only a (popped) triangle group
    kOverflow = 2,   ///< the stack is full (TraceStatus::kStackOverflow)
    kBadIndex = 3,   ///< the child index is outside NODE (TraceStatus::kBadIndex)
};

/// Node step, first part (call only when has_node_work()): takes the next child of the
/// node group (highest bit first) off the group and returns its NODE index, not yet
/// checked against the section's size. The group's highest bit is a node bit (>= 24),
/// so its slot is bit & 7 (not bit - 24: one instruction less in the kernel).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE uint32_t take_next_child(CwbvhLane<kTest>& l) {
    const uint32_t hits = l.node_group.hits;
    const int bit = highest_bit(hits);
    l.node_group.hits = hits & ~(1u << bit);
    const uint32_t slot = (uint32_t(bit) & 7u) ^ l.nray.octinv;
    return l.node_group.base + uint32_t(popcount32(hits & 0xFFu & ((1u << slot) - 1u)));
}

/// Node step, first half, whole: take_next_child, then pushes the rest of the group if
/// it still has node children, and checks the index. Without node work (the lane popped
/// a triangle group, which pop_if_idle put in tri_group) there is no node step. The warp
/// model runs this; the kernel runs the same parts inline, in the same order.
template <TriangleTest kTest, class Stack>
CWBVH_HD CWBVH_INLINE NodeStep next_node(CwbvhLane<kTest>& l, Stack& stack, uint32_t node_count, uint32_t& index) {
    if (!l.has_node_work()) return NodeStep::kNoNode;
    index = take_next_child(l);
    if (l.has_node_work() && !stack.push(l.node_group)) return NodeStep::kOverflow;
    if (index >= node_count) return NodeStep::kBadIndex;
    return NodeStep::kVisit;
}

/// Node step, second half: tests the eight child boxes of the loaded node and makes
/// its hit children the new node and triangle groups. Node: NodeWords (the kernel,
/// load_node_words) or CwbvhNode (the host). frame_word: the scene's
/// NodeScale::frame_word, the fast test's scene word (the kernel passes it from its launch
/// parameters; see intersect_node_fast).
template <TriangleTest kTest, class Node>
CWBVH_HD CWBVH_INLINE void visit_node(CwbvhLane<kTest>& l, const Node& node, uint32_t frame_word) {
    const uint32_t hitmask = intersect_node_dispatch(node, l.nray, l.tmin, l.tmax, frame_word);
    l.node_group = StackEntry{node_child_base(node), (hitmask & 0xFF000000u) | node_imask(node)};
    l.tri_group = StackEntry{node_tri_base(node), hitmask & 0x00FFFFFFu};
}

/// Triangle step, first part (call only when wants_triangles()): takes the next
/// triangle of the group (highest bit first) off the group and returns its TRIS index,
/// not yet checked against the section's size.
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE uint32_t take_next_triangle(CwbvhLane<kTest>& l) {
    const int bit = highest_bit(l.tri_group.hits);
    l.tri_group.hits &= ~(1u << bit);
    return l.tri_group.base + uint32_t(bit);
}

/// Triangle step, first half: take_next_triangle, checked: its TRIS index, or
/// kNoTriangle when the index is outside TRIS (TraceStatus::kBadIndex).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE uint32_t next_triangle(CwbvhLane<kTest>& l, uint32_t tri_count) {
    const uint32_t ti = take_next_triangle(l);
    return ti < tri_count ? ti : kNoTriangle;
}

/// Triangle step, second half: tests the loaded triangle `ti`; a hit shrinks tmax
/// and becomes the closest hit, and th holds its t, u, v. Returns true on a hit.
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE bool test_triangle(CwbvhLane<kTest>& l, const TriangleRecord& tri, uint32_t ti,
                                         TriangleHit& th) {
    // with_org: the origin from nray (the same values; one copy in registers).
    if (!l.tri_test.with_org(l.nray.org)(tri, l.tmin, l.tmax, th)) return false;
    l.tmax = th.t;
    l.hit_tri = ti;
    return true;
}
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE bool test_triangle(CwbvhLane<kTest>& l, const TriangleRecord& tri, uint32_t ti) {
    TriangleHit th;
    return test_triangle(l, tri, ti, th);
}

/// Outcome of test_triangle_deferred.
enum class TriangleStep : uint32_t {
    kMiss = 0,       ///< no hit, decided in float (edge signs, or T certainly out of range)
    kWholeMiss = 1,  ///< no hit, decided by the whole test (its double-precision path)
    kDeferred = 2,   ///< a hit, certainly the closest so far; t, u, v wait for finalize_hit
    kExact = 3,      ///< a hit with its t, u, v in th (the whole test ran)
};
/// A hit: kDeferred or kExact.
CWBVH_HD CWBVH_INLINE bool is_hit(TriangleStep s) { return uint32_t(s) >= uint32_t(TriangleStep::kDeferred); }

/// What test_triangle_deferred did with a deferred closest hit it had to finish.
enum class PrevHit : uint32_t { kNone = 0, kFinished = 1, kFailed = 2 };

/// The whole triangle test of TRIS[index] over [tmin, tmax] for a lane (whole_test): the
/// `whole` argument of test_triangle_deferred. `load` reads a triangle by TRIS index (the
/// kernel through the read-only cache, the warp model from memory).
template <TriangleTest kTest, class Load>
struct WholeTest {
    TriangleIntersector<kTest> test;
    float tmin;
    Load load;
    CWBVH_HD bool operator()(uint32_t index, float tmax, TriangleHit& th) const {
        return test(load(index), tmin, tmax, th);
    }
};
template <TriangleTest kTest, class Load>
CWBVH_HD CWBVH_INLINE WholeTest<kTest, Load> whole_test(const CwbvhLane<kTest>& l, const Load& load) {
    return WholeTest<kTest, Load>{l.tri_test.with_org(l.nray.org), l.tmin, load};
}

/// Finishes a deferred hit (l.hit_deferred(tlo)) at refill time: its t, u, v from its
/// triangle `tri` (TRIS index l.hit_tri) by watertight_finish, which gives what the whole
/// test would (watertight_range_interval certified the hit) with fewer registers; tmax and
/// tlo become t. The kernel runs it for all of a warp's ended lanes at once (traverse_gpu.h).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE void finalize_hit(CwbvhLane<kTest>& l, float& tlo, const TriangleRecord& tri, TriangleHit& th) {
    if constexpr (kTest == TriangleTest::kWatertight) {
        WatertightRay w = l.tri_test.w;
        for (int a = 0; a < 3; ++a) w.org[a] = l.nray.org[a];  // as with_org
        th = watertight_finish(w, tri.v0, tri.v1, tri.v2);
    } else {
        (void)tri;
        th = TriangleHit{l.tmax, 0.0f, 0.0f};  // never deferred
    }
    l.tmax = tlo = th.t;
}

/// Triangle step, second half, as the GPU kernel runs it (issue 18): the watertight
/// test's double-precision hit distance and its u, v are deferred while float alone
/// proves the triangle the closest hit so far. Most triangles whose edge signs agree
/// are hits (sponza_dabrovic nave, diffuse bounce 1, 512x512: 403k of 407k past the float
/// range stage), and the warp ran the double path in 67 % of its triangle rounds (480x270);
/// a deferred hit costs a float interval, and the warp finishes its deferred hits together
/// when it refills (then 6 % of the rounds and 0.07 refills a ray: `cwbvh model`,
/// bench/results/model/2026-11-27-deferred-hits).
///   - edge signs mixed, or T certainly outside [tmin, tmax]: kMiss;
///   - all three edge functions finite and nonzero, and watertight_range_interval kInside (float t
///     certainly in [lo, hi], tmin <= lo, hi <= tlo: closer than the closest hit, deferred
///     or not): the new closest hit, deferred (tmax = hi, tlo = lo): kDeferred;
///   - otherwise the whole test (`whole`: TRIS index, tmax -> hit, t, u, v) decides,
///     against the exact distance of the closest hit so far: kExact on a hit (tmax = tlo =
///     t), kWholeMiss if not. With a deferred hit, the whole test runs on that hit's
///     triangle instead (prev_state kFinished; kFailed if it says no, which cannot happen
///     and the warp model counts), and this triangle goes back into the group for the next
///     round (kWholeMiss): one call site of the whole test, not two.
/// th holds the t, u, v of the closest hit whenever the whole test found them: on kExact,
/// and on kWholeMiss when a deferred hit was finished.
/// The hit found is the reference's (traverse.h): a triangle is taken exactly when its
/// float t is <= the exact t of the closest hit so far, as there; tmax >= that t at all
/// times, so no node or triangle the reference tests is culled. (The converse does not
/// hold: a lane may visit a few nodes the reference culls. In a valid file that changes
/// nothing; in a corrupt one such a node's bad child index could end the ray with
/// kBadIndex where the reference ends it kOk.) The fast test (Moller-
/// Trumbore, all float) has nothing to defer: it is test_triangle.
template <TriangleTest kTest, class Whole>
CWBVH_HD CWBVH_INLINE TriangleStep test_triangle_deferred(CwbvhLane<kTest>& l, float& tlo, const TriangleRecord& tri,
                                                          uint32_t ti, const Whole& whole, TriangleHit& th,
                                                          PrevHit& prev_state) {
    prev_state = PrevHit::kNone;
    if constexpr (kTest == TriangleTest::kWatertight) {
        WatertightRay w = l.tri_test.w;
        for (int a = 0; a < 3; ++a) w.org[a] = l.nray.org[a];  // as with_org
        WatertightEdges e;
        if (!watertight_edges(w, tri.v0, tri.v1, tri.v2, e)) return TriangleStep::kMiss;
        // Edge functions that are finite and not 0 have the exact signs of the sheared
        // coordinates' (rounding is monotone), and those coordinates are finite (one of
        // +-inf makes an edge function +-inf or NaN), so the whole test's double path
        // cannot reject the triangle (watertight_finish).
        const bool certain = is_finite_nonzero_f(e.eu) && is_finite_nonzero_f(e.ev) && is_finite_nonzero_f(e.ew);
        float lo, hi;
        const RangeVerdict v = watertight_range_interval(w, tri.v0, tri.v1, tri.v2, l.tmin, tlo, l.tmax, lo, hi);
        if (v == RangeVerdict::kMiss) return TriangleStep::kMiss;
        if (v == RangeVerdict::kInside && certain) {
            l.tmax = hi;
            tlo = lo;
            l.hit_tri = ti;
            return TriangleStep::kDeferred;
        }
        // One call site of the whole test. With a deferred hit, that hit's triangle is
        // finished in this round and this triangle goes back into the group, to be tested
        // in the next round against the exact distance.
        const bool finishing = l.hit_deferred(tlo);
        if (finishing) l.tri_group.hits |= 1u << (ti - l.tri_group.base);
        TriangleHit h{l.tmax, 0.0f, 0.0f};
        const bool hit = whole(finishing ? l.hit_tri : ti, l.tmax, h);
        if (finishing) {
            prev_state = hit ? PrevHit::kFinished : PrevHit::kFailed;
            l.tmax = tlo = h.t;
            th = h;
            return TriangleStep::kWholeMiss;
        }
        if (!hit) return TriangleStep::kWholeMiss;
        l.tmax = tlo = h.t;
        l.hit_tri = ti;
        th = h;
        return TriangleStep::kExact;
    } else {
        (void)whole;
        if (!test_triangle(l, tri, ti, th)) return TriangleStep::kMiss;
        tlo = th.t;
        return TriangleStep::kExact;
    }
}

/// Postpones the triangle group (paper 4.2): pushes it and clears it. False when
/// the stack is full (TraceStatus::kStackOverflow).
template <TriangleTest kTest, class Stack>
CWBVH_HD CWBVH_INLINE bool postpone_triangles(CwbvhLane<kTest>& l, Stack& stack) {
    if (!stack.push(l.tri_group)) return false;
    l.tri_group.hits = 0;
    return true;
}

/// End of an iteration: a lane whose node group is used up pops the next group into
/// the group it is: a node group (node bits) becomes the node group, a postponed
/// triangle group the triangle group, to be tested in the next iteration's rounds.
/// (Until issue 18 the node group took either, and the next node step moved a triangle
/// group over; that second branch of the kernel's node step cost register copies that
/// nvcc ran on every node step.) The triangle group is empty here: every iteration's
/// triangle rounds run until no lane wants triangles. Returns true when the ray is done
/// (nothing left on the stack).
template <TriangleTest kTest, class Stack>
CWBVH_HD CWBVH_INLINE bool pop_if_idle(CwbvhLane<kTest>& l, Stack& stack) {
    if (l.has_node_work()) return false;
    if (stack.empty()) return true;
    const StackEntry e = stack.pop();
    if (e.hits > 0x00FFFFFFu)
        l.node_group = e;
    else
        l.tri_group = e;
    return false;
}


}  // namespace cwbvh
