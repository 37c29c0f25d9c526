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
//   - the closest hit so far is the TRIS index of its triangle plus tmax (which IS
//     the hit distance); its u, v go to shared memory at each hit (test_triangle's
//     TriangleHit; the kernel's s_uv, the warp model's Lane), and the primitive id is
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
    float tmax;           ///< current interval end = distance of the closest hit so far
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
