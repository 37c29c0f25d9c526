// CWBVH traversal loop (Ylitie, Karras, Laine 2017, section 4 and its pseudocode),
// written once for the CPU reference and the CUDA kernels.
//
// State: the current node group and triangle group, and a stack of compressed
// 8-byte entries {base, hits} (paper section 4.1):
//   node group:     base = index in NODE of the first internal child,
//                   hits = (one bit per not-yet-visited hit child at 24 + (slot ^ octinv))
//                          | imask of the parent in bits 0..7 (to find the child's index);
//   triangle group: base = index in TRIS of the parent's first triangle,
//                   hits = one bit per triangle still to test, bits 0..23.
// A group with hits > 0x00FFFFFF is a node group; anything else a triangle group.
// Children are taken highest bit first: bit 24 + (s ^ octinv) is highest for the
// slot the compiler assigned to the ray's octant (octant-based order, paper 3.2).
//
// Stack bound: without postponing, each push stores the rest of one node group
// before descending one level, and a group is pushed only while it still holds
// unvisited children, so at most one entry per level of the current path is live:
// entries <= depth - 1 (depth = number of node levels, root = 1). Postponing (GPU)
// adds at most one triangle group per level: entries <= 2 * (depth - 1).
// The stack reports a full push instead of writing past its end; the traversal then
// stops and returns TraceStatus::kStackOverflow (the hit is not trustworthy).
// With kCpuStackSize = 64 a tree of depth <= 65 (33 with postponing) never overflows.
#pragma once

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/kernels/fp.h"
#include "cwbvh/kernels/node_intersect.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/triangle_intersect.h"

/// The loop steps below are inlined into every loop that calls them on the host
/// too (GCC kept cwbvh_node_step out of line under plain `inline`, which cost the
/// CPU reference ~4 %: its groups went through memory).
#if defined(__CUDACC__)
#define CWBVH_STEP_INLINE __forceinline__
#else
#define CWBVH_STEP_INLINE inline __attribute__((always_inline))
#endif

namespace cwbvh {

enum class TraceStatus : uint32_t {
    kOk = 0,             ///< hit or miss, exact answer of the traversal
    kInvalidRay = 1,     ///< ray not traceable (ray.h); answered with a miss
    kStackOverflow = 2,  ///< stack too small for this tree; hit is a lower bound of nothing
    kBadIndex = 3,       ///< node or triangle index out of range: corrupt tree
    kWrongScene = 4,     ///< an inline query compiled for the other kind of scene (query.h, SceneLevels): a miss
};

enum class HitMode : uint32_t { kClosest = 0, kAny = 1 };

/// Per-ray work counters (heatmaps, benchmarks).
struct TraceCounters {
    uint32_t nodes;      ///< wide (or binary) nodes whose children were tested
    uint32_t triangles;  ///< triangle tests
};

struct StackEntry {
    uint32_t base;
    uint32_t hits;
};

/// Fixed-size stack in registers/local memory. A GPU kernel may pass its own
/// stack type (shared memory + spill) with the same three members.
template <int kSize>
struct LocalStack {
    StackEntry entries[kSize];
    int size = 0;
    CWBVH_HD bool push(StackEntry e) {
        if (size >= kSize) return false;
        entries[size++] = e;
        return true;
    }
    CWBVH_HD bool empty() const { return size == 0; }
    CWBVH_HD StackEntry pop() { return entries[--size]; }
};

inline constexpr int kCpuStackSize = 64;

/// Triangle postponing policy (paper 4.2: push the triangle group while fewer than
/// 20% of the warp's lanes want to test triangles). The CPU never postpones.
struct NoPostpone {
    CWBVH_HD bool operator()() const { return false; }
};

/// Node step (paper 4.1), shared by traverse_cwbvh and the two-level traversal
/// (traverse_two_level.h): a node group takes its next child (highest bit first),
/// pushes the rest while it still holds node children, and the child's eight boxes
/// become the new node and triangle groups; a group without node bits is a
/// (popped) triangle group and becomes the triangle group. `nodes` is the array
/// the group's base indexes (NODE, or TLAS at the top level). kOk, or
/// kStackOverflow / kBadIndex. The node test: intersect_node_dispatch (the reference
/// arithmetic unless the ray's set-up enabled the fast test; frame_word: the scene's
/// NodeScale::frame_word, used only then).
template <class Stack>
CWBVH_HD CWBVH_STEP_INLINE TraceStatus cwbvh_node_step(StackEntry& node_group, StackEntry& tri_group, const NodeRay& nray,
                                                  float tmin, float tmax, const CwbvhNode* nodes, uint32_t node_count,
                                                  Stack& stack, uint32_t& n_nodes, uint32_t frame_word = 0u) {
    if (node_group.hits <= 0x00FFFFFFu) {
        tri_group = node_group;
        node_group = StackEntry{0u, 0u};
        return TraceStatus::kOk;
    }
    const int bit = highest_bit(node_group.hits);
    const uint32_t base = node_group.base;
    const uint32_t imask = node_group.hits & 0xFFu;
    node_group.hits &= ~(1u << bit);
    if (node_group.hits > 0x00FFFFFFu && !stack.push(node_group)) return TraceStatus::kStackOverflow;
    const uint32_t slot = (uint32_t(bit) - 24u) ^ nray.octinv;
    const uint32_t index = base + uint32_t(popcount32(imask & ((1u << slot) - 1u)));
    if (index >= node_count) return TraceStatus::kBadIndex;
#if defined(__CUDA_ARCH__)
    const NodeWords node = load_node_words(nodes + index);  // words, not bytes (NodeWords)
#else
    const CwbvhNode& node = nodes[index];
#endif
    ++n_nodes;
    const uint32_t hitmask = intersect_node_dispatch(node, nray, tmin, tmax, frame_word);
    node_group = StackEntry{node_child_base(node), (hitmask & 0xFF000000u) | node_imask(node)};
    tri_group = StackEntry{node_tri_base(node), hitmask & 0x00FFFFFFu};
    return TraceStatus::kOk;
}

/// Takes the next leaf record of a triangle group (highest bit first): its index
/// (TRIS, or INST at the top level). Call only while group.hits != 0.
CWBVH_HD CWBVH_STEP_INLINE uint32_t take_leaf_record(StackEntry& group) {
    const int bit = highest_bit(group.hits);
    group.hits &= ~(1u << bit);
    return group.base + uint32_t(bit);
}

/// Triangle step: tests tris[ti] (ti < tri_count checked by the caller) against
/// [tmin, tmax]; a hit shrinks tmax to its t (closed interval) and is written to hit.
template <TriangleTest kTest>
CWBVH_HD CWBVH_STEP_INLINE bool cwbvh_triangle_step(const TriangleIntersector<kTest>& tri_test, const TriangleRecord& tri,
                                               float tmin, float& tmax, Hit& hit) {
    TriangleHit th;
    if (!tri_test(tri, tmin, tmax, th)) return false;
    tmax = th.t;
    hit = Hit{th.t, th.u, th.v, tri.prim};
    return true;
}

/// Traverse one ray. nodes[0] is the root (internal). hit receives the closest hit
/// (HitMode::kClosest) or the first found (kAny), or make_miss().
/// scale: the scene's constants of the fast node test (node_scale() over NODE, as
/// DeviceScene::upload computes them); with them the node steps take intersect_node_fast
/// wherever the ray's set-up admits it, as the kernels do. NodeScale{} (the default, the
/// CPU reference): the reference node test everywhere. Both tests are conservative, so
/// the hit is the same (query.h, tests/kernels/query_test.cpp).
/// hit_record (optional): the TRIS index of the hit's record (kInvalidIndex for a miss),
/// for a caller that reads the triangle (query.h).
template <TriangleTest kTest, HitMode kMode, class Stack, class Postpone = NoPostpone>
CWBVH_HD CWBVH_INLINE TraceStatus traverse_cwbvh(const CwbvhNode* nodes, uint32_t node_count,
                                                 const TriangleRecord* tris, uint32_t tri_count,
                                                 const Ray& ray, Hit& hit, Stack& stack,
                                                 TraceCounters* counters = nullptr,
                                                 Postpone postpone = Postpone(),
                                                 const NodeScale& scale = NodeScale{},
                                                 uint32_t* hit_record = nullptr) {
    hit = make_miss();
    if (hit_record) *hit_record = kInvalidIndex;
    if (!ray_is_traceable(ray) || node_count == 0) return TraceStatus::kInvalidRay;
    NodeRay nray = make_node_ray(ray);
    // The fast test measures from tmin with its sign bit clear (a -0 tmin is the same
    // closed interval as +0: cwbvh_lane.h). Without the scene's constants it stays off.
    if (scale.usable != 0) enable_fast_node_test(nray, scale, ray.dir, ray.tmin == 0.0f ? 0.0f : ray.tmin);
    const TriangleIntersector<kTest> tri_test(ray);
    const float tmin = ray.tmin;
    float tmax = ray.tmax;  // shrinks to the closest hit so far (closed interval)
    uint32_t n_nodes = 0, n_tris = 0;
    TraceStatus status = TraceStatus::kOk;

    // The root as a node group of one: bit 31 set, imask 0, so whatever slot bit 31
    // maps to, the index is base + popc(0) = 0 (paper; the root must be internal).
    StackEntry node_group{0u, 0x80000000u};
    StackEntry tri_group{0u, 0u};
    for (;;) {
        status = cwbvh_node_step(node_group, tri_group, nray, tmin, tmax, nodes, node_count, stack, n_nodes,
                                 scale.frame_word);
        if (status != TraceStatus::kOk) break;

        bool done = false;
        while (tri_group.hits != 0) {
            if (postpone()) {
                if (!stack.push(tri_group)) status = TraceStatus::kStackOverflow;
                break;
            }
            const uint32_t ti = take_leaf_record(tri_group);
            if (ti >= tri_count) {
                status = TraceStatus::kBadIndex;
                break;
            }
            ++n_tris;
            if (cwbvh_triangle_step(tri_test, tris[ti], tmin, tmax, hit)) {
                if (hit_record) *hit_record = ti;
                if (kMode == HitMode::kAny) {
                    done = true;
                    break;
                }
            }
        }
        if (done || status != TraceStatus::kOk) break;

        if (node_group.hits <= 0x00FFFFFFu) {
            if (stack.empty()) break;
            node_group = stack.pop();
        }
    }
    if (counters) {
        counters->nodes = n_nodes;
        counters->triangles = n_tris;
    }
    return status;
}

}  // namespace cwbvh
