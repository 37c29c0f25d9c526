// One lane of the BVH2 baseline traversal: the per-ray state and the two steps
// the GPU kernel (traverse_gpu_bvh2.h, trace_bvh2_persistent) runs for each of
// its 32 lanes, written once for the kernel, the CPU reference (traverse_bvh2
// below: a warp of one lane) and a CPU lock-step warp model. Host/device, no
// CUDA intrinsics: the kernel hands the steps its __ldg loader.
//
// The kernel is Aila, Karras and Laine 2012 ("Understanding the efficiency of ray
// traversal on GPUs - Kepler and Fermi addendum", kernel kepler_dynamic_fetch),
// itself Aila & Laine 2009 ("Understanding the Efficiency of Ray Traversal on
// GPUs", HPG 2009) with the 2009 paper's best variants combined:
//   - while-while traversal: an inner loop over internal nodes, then one over leaves;
//   - speculative traversal and leaf postponing (2009, section 4): a lane that
//     reaches a leaf parks it in `leaf` and keeps descending until every lane of
//     the warp has a leaf to test, so the leaf loop runs with more lanes;
//   - persistent threads with dynamic fetch (2009 section 3; 2012): a warp pulls
//     new rays for its finished lanes as soon as fewer than
//     kBvh2DynamicFetchThreshold lanes are still busy, one atomicAdd per warp.
//
// Lane state (paper names in brackets):
//   node [nodeAddr]   >= 0 and < kBvh2Sentinel: internal node to visit next;
//                     < 0: a leaf found while another one was postponed;
//                     kBvh2Sentinel [EntrypointSentinel]: nothing left to visit.
//   leaf [leafAddr]   < 0: the postponed leaf; >= 0: none.
//   stack             far children (in Bvh2LaneMemory), one per level of the current path at most
//                     (postponing takes a popped entry out, it never adds one),
//                     so a tree of <= 64 levels (rule 5606) fits kBvh2LaneStackEntries.
// A leaf is a packed word ~((first << leaf_bits) | (count - 1)): negative, first
// TRIS record and record count (1..4) of a BV2L leaf in 31 bits (leaf_bits = 2,
// TRIS <= 2^29, rule 4011), or of a legacy BVH2 leaf (leaf_count 0 = 1 record;
// leaf_bits = 0 when TRIS > 2^29, which only a BVH2 file may have). The leaf loop
// walks a leaf by rewriting the word to (first + 1, count - 1).
//
// Warp-level control, exactly what trace_bvh2_persistent does (a model that runs
// these steps for 32 lanes in lock step must apply the same rules):
//   1. Store: at the top of each warp iteration, every lane that is done
//      (bvh2_lane_done) and holds a ray stores its hit and status.
//   2. Fetch [dynamic fetch]: unless the pool is known to be exhausted, the warp
//      ballots its done lanes; if there are any, the lowest of them does ONE
//      atomicAdd(next_ray, number of done lanes) and the done lanes take the ids
//      base + (their rank among the done lanes); ids >= ray_count are not taken;
//      a base >= ray_count marks the pool exhausted (no further fetches). A lane
//      whose new ray is untraceable is done at once (kInvalidRay, miss) and is
//      stored and refilled on the next warp iteration.
//      If no lane is busy: leave the kernel when the pool is exhausted, else go to 1.
//   3. Trace, repeated:
//      a. node phase: while ANY lane is in the node loop (bvh2_lane_in_nodes) with
//         no postponed leaf, every lane in the node loop runs one
//         bvh2_lane_node_step (lanes that already hold a leaf traverse
//         speculatively); i.e. the warp leaves the phase when every lane has a
//         postponed leaf or cannot traverse (AKL 2012's vote on leafAddr);
//      b. leaf phase: while ANY lane has a postponed leaf, each lane that has one
//         runs one bvh2_lane_triangle_step (the step moves on to a second found
//         leaf by itself, as the paper's leaf loop does);
//      c. vote: count the busy lanes (not done); go back to 1 when none is busy,
//         or when the pool is not exhausted and fewer than
//         kBvh2DynamicFetchThreshold are busy; else repeat 3.
//   Node/triangle counters (stats runs only) count one per node step / triangle step,
//   speculative ones included: a GPU run reports more nodes per ray than the CPU
//   reference, which is a warp of one lane and never speculates.
//
// Hits: the same TriangleIntersector (watertight or fast) as every traversal. A
// candidate replaces the current hit if it is closer, or at the same t with a
// smaller prim: the closest hit is then the smallest (t, prim) over the triangles
// the traversal reaches, whatever order the leaves come in, so speculative
// traversal (which may test extra leaves, all at t >= the final one) gives the
// CPU reference's hit bit for bit. Any-hit queries stop at the first hit.
#pragma once

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/traverse_bvh2.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

/// Stack entries per lane (one per tree level; rule 5606 bounds BVH2/BV2L at 64 levels).
inline constexpr int kBvh2LaneStackEntries = 64;
/// AKL 2012's DYNAMIC_FETCH_THRESHOLD: refill when fewer lanes than this are busy.
inline constexpr int kBvh2DynamicFetchThreshold = 20;
/// Aila & Laine's EntrypointSentinel: "nothing left to visit" (never a valid node index).
inline constexpr int32_t kBvh2Sentinel = 0x76543210;
/// A `leaf` value >= 0: no postponed leaf.
inline constexpr int32_t kBvh2NoLeaf = 0;
/// TRIS records above which a packed leaf has no room for a count (legacy BVH2 only).
inline constexpr uint32_t kBvh2PackedTrisLimit = uint32_t(kMaxBvh2LeafTris);

/// The tree a lane walks. node_count is capped at kBvh2Sentinel (indices at or
/// above it are reported as bad, like any index outside the array).
struct Bvh2Scene {
    const Bvh2Node* nodes;
    uint32_t node_count;
    const TriangleRecord* tris;
    uint32_t tri_count;
    uint32_t leaf_bits;  ///< bits of count - 1 in a packed leaf: 2, or 0 if TRIS > 2^29
};

CWBVH_HD CWBVH_INLINE Bvh2Scene make_bvh2_scene(const Bvh2Node* nodes, uint32_t node_count,
                                               const TriangleRecord* tris, uint32_t tri_count) {
    Bvh2Scene s;
    s.nodes = nodes;
    s.node_count = node_count < uint32_t(kBvh2Sentinel) ? node_count : uint32_t(kBvh2Sentinel);
    s.tris = tris;
    s.tri_count = tri_count;
    s.leaf_bits = tri_count <= kBvh2PackedTrisLimit ? 2u : 0u;
    return s;
}

/// Plain loads (CPU); the CUDA kernel passes a loader with the same two calls.
struct Bvh2PlainLoad {
    CWBVH_HD Bvh2Node operator()(const Bvh2Node* p) const { return *p; }
    CWBVH_HD TriangleRecord operator()(const TriangleRecord* p) const { return *p; }
};

/// The part of a lane's state that lives in local memory on the GPU: the stack
/// (indexed at run time) and the hit's triangle and barycentrics (written at hits
/// only, read once when the ray is stored; 3-4 registers fewer, measured with
/// ptxas). Apart from Bvh2Lane because nvcc places a struct that holds an indexed
/// array in local memory whole; Bvh2Lane's scalars stay in registers.
struct Bvh2LaneMemory {
    int32_t stack[kBvh2LaneStackEntries];
    float u, v;     ///< barycentrics of the hit (its t is Bvh2Lane::tmax)
    uint32_t prim;  ///< hit triangle's prim, kMissPrim for none
};

template <TriangleTest kTest>
struct Bvh2Lane {
    Bvh2Ray ray;                          ///< origin, RN(1/d), axis flags (box test)
    TriangleIntersector<kTest> tri_test;  ///< per-ray triangle test set-up
    float tmin, tmax;                     ///< tmax: the closest hit's t (or the ray's tmax)
    int32_t node;                         ///< [nodeAddr]
    int32_t leaf;                         ///< [leafAddr]
    int32_t sp;                           ///< entries on the lane's stack
    TraceStatus status;

    /// A lane without a ray: done, answer a miss.
    CWBVH_HD Bvh2Lane()
        : ray{}, tri_test(Ray{{0.0f, 0.0f, 0.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, 0.0f}), tmin(0.0f), tmax(0.0f),
          node(kBvh2Sentinel), leaf(kBvh2NoLeaf), sp(0), status(TraceStatus::kInvalidRay) {}
};

/// Done: nothing to visit and no postponed leaf (the hit and status are final).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE bool bvh2_lane_done(const Bvh2Lane<kTest>& l) {
    return l.node == kBvh2Sentinel && l.leaf >= 0;
}

/// In the node loop: node is an internal node index (AKL's unsigned compare).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE bool bvh2_lane_in_nodes(const Bvh2Lane<kTest>& l) {
    return uint32_t(l.node) < uint32_t(kBvh2Sentinel);
}

/// Has a postponed leaf (the leaf loop's condition).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE bool bvh2_lane_has_leaf(const Bvh2Lane<kTest>& l) {
    return l.leaf < 0;
}

/// The lane's answer (final once bvh2_lane_done).
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE Hit bvh2_lane_hit(const Bvh2Lane<kTest>& l, const Bvh2LaneMemory& m) {
    return m.prim == kMissPrim ? make_miss() : Hit{l.tmax, m.u, m.v, m.prim};
}

template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE void bvh2_lane_stop(Bvh2Lane<kTest>& l, TraceStatus status) {
    l.node = kBvh2Sentinel;
    l.leaf = kBvh2NoLeaf;
    l.sp = 0;
    l.status = status;
}

template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE int32_t bvh2_lane_pop(Bvh2Lane<kTest>& l, const Bvh2LaneMemory& m) {
    return l.sp > 0 ? m.stack[--l.sp] : kBvh2Sentinel;
}

/// Starts ray `r`. An untraceable ray (ray.h) or an empty tree: the lane is done
/// at once with kInvalidRay and a miss, and false is returned.
template <TriangleTest kTest>
CWBVH_HD CWBVH_INLINE bool bvh2_lane_start(Bvh2Lane<kTest>& l, Bvh2LaneMemory& m, const Ray& r,
                                            const Bvh2Scene& s) {
    m.u = m.v = 0.0f;
    m.prim = kMissPrim;
    l.sp = 0;
    l.leaf = kBvh2NoLeaf;
    if (!ray_is_traceable(r) || s.node_count == 0) {
        l.node = kBvh2Sentinel;
        l.status = TraceStatus::kInvalidRay;
        return false;
    }
    l.ray = make_bvh2_ray(r);
    l.tri_test = TriangleIntersector<kTest>(r);
    l.tmin = r.tmin;
    l.tmax = r.tmax;
    l.node = 0;  // the root, internal
    l.status = TraceStatus::kOk;
    return true;
}

/// The traversal word of child `child` (leaf_count as stored): an internal index,
/// or a packed leaf. False for an index outside the tree (kBadIndex).
CWBVH_HD CWBVH_INLINE bool bvh2_child_word(int32_t child, uint32_t leaf_count, const Bvh2Scene& s, int32_t& word) {
    if (child >= 0) {
        word = child;
        return uint32_t(child) < s.node_count;
    }
    const uint32_t first = uint32_t(~child);                 // < 2^31
    const uint32_t count = leaf_count == 0 ? 1u : leaf_count;  // BVH2 (1.0): 0 = one record
    if (count > (1u << s.leaf_bits) || first >= s.tri_count || count > s.tri_count - first) return false;
    // first < tri_count <= 2^29 when leaf_bits = 2: the shift stays below 2^31.
    word = ~int32_t((first << s.leaf_bits) | (count - 1u));
    return true;
}

/// One internal node step: fetch node `l.node`, test both child boxes, go to the
/// nearer hit child and push the farther (or pop when neither is hit); then, if
/// that reached a leaf and none is postponed yet, postpone it and pop the next
/// entry [AKL 2012: "first leaf => postpone and continue traversal"].
/// Requires bvh2_lane_in_nodes(l).
template <TriangleTest kTest, class Load = Bvh2PlainLoad>
CWBVH_HD CWBVH_INLINE void bvh2_lane_node_step(Bvh2Lane<kTest>& l, Bvh2LaneMemory& m, const Bvh2Scene& s,
                                                const Load& load = Load{}) {
    const Bvh2Node n = load(s.nodes + l.node);
    const float lo0[3] = {n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, hi0[3] = {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z};
    const float lo1[3] = {n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, hi1[3] = {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z};
    float t0 = 0.0f, t1 = 0.0f;
    const bool h0 = intersect_box_robust(l.ray, lo0, hi0, l.tmin, l.tmax, t0);
    const bool h1 = intersect_box_robust(l.ray, lo1, hi1, l.tmin, l.tmax, t1);
    int32_t c0 = 0, c1 = 0;
    if ((h0 && !bvh2_child_word(n.child[0], n.leaf_count[0], s, c0)) ||
        (h1 && !bvh2_child_word(n.child[1], n.leaf_count[1], s, c1))) {
        bvh2_lane_stop(l, TraceStatus::kBadIndex);
        return;
    }
    if (h0 && h1) {
        // Near child first (ties: child 0); the far one waits on the stack.
        const bool swap = t1 < t0;
        if (l.sp >= kBvh2LaneStackEntries) {
            bvh2_lane_stop(l, TraceStatus::kStackOverflow);
            return;
        }
        m.stack[l.sp++] = swap ? c0 : c1;
        l.node = swap ? c1 : c0;
    } else if (h0 || h1) {
        l.node = h0 ? c0 : c1;
    } else {
        l.node = bvh2_lane_pop(l, m);
    }
    if (l.node < 0 && l.leaf >= 0) {
        l.leaf = l.node;
        l.node = bvh2_lane_pop(l, m);
    }
}

/// One triangle of the postponed leaf: test its next record; a closer hit (or an
/// equally close one with a smaller prim) becomes the hit, and any hit ends an
/// any-hit query. After the leaf's last record, the leaf found during speculative
/// traversal (node < 0), if any, becomes the postponed leaf and the next entry is
/// popped [AKL 2012: "another leaf was postponed => process it as well"].
/// Requires bvh2_lane_has_leaf(l).
template <HitMode kMode, TriangleTest kTest, class Load = Bvh2PlainLoad>
CWBVH_HD CWBVH_INLINE void bvh2_lane_triangle_step(Bvh2Lane<kTest>& l, Bvh2LaneMemory& m, const Bvh2Scene& s,
                                                   const Load& load = Load{}) {
    const uint32_t word = ~uint32_t(l.leaf);  // (first << leaf_bits) | (count - 1)
    const TriangleRecord tri = load(s.tris + (word >> s.leaf_bits));
    TriangleHit th;
    // with_org: the origin from the box test's ray (the same values; one copy in registers).
    if (l.tri_test.with_org(l.ray.org)(tri, l.tmin, l.tmax, th) && (th.t < l.tmax || tri.prim < m.prim)) {
        l.tmax = th.t;
        m.u = th.u;
        m.v = th.v;
        m.prim = tri.prim;
        if (kMode == HitMode::kAny) {
            bvh2_lane_stop(l, TraceStatus::kOk);
            return;
        }
    }
    const uint32_t rest = word & ((1u << s.leaf_bits) - 1u);  // records left after this one
    if (rest != 0) {
        l.leaf = ~int32_t(word + (1u << s.leaf_bits) - 1u);  // (first + 1, count - 1)
        return;
    }
    l.leaf = l.node;
    if (l.node < 0) l.node = bvh2_lane_pop(l, m);
}

/// Traverse one ray over a BVH2 or BV2L section (nodes[0] is the root): the lane
/// steps above run as a warp of one lane, i.e. the while-while loop without
/// speculation. hit receives the closest (kClosest) or first found (kAny) hit; the
/// status says whether the answer is exact (kOk), the ray untraceable (miss), or
/// the tree too deep / corrupt (the hit found so far).
template <TriangleTest kTest, HitMode kMode>
CWBVH_HD CWBVH_INLINE TraceStatus traverse_bvh2(const Bvh2Node* nodes, uint32_t node_count,
                                                const TriangleRecord* tris, uint32_t tri_count,
                                                const Ray& ray, Hit& hit,
                                                TraceCounters* counters = nullptr) {
    const Bvh2Scene s = make_bvh2_scene(nodes, node_count, tris, tri_count);
    Bvh2Lane<kTest> l;
    Bvh2LaneMemory m;
    uint32_t n_nodes = 0, n_tris = 0;
    if (bvh2_lane_start(l, m, ray, s)) {
        while (!bvh2_lane_done(l)) {
            while (bvh2_lane_in_nodes(l) && !bvh2_lane_has_leaf(l)) {
                bvh2_lane_node_step(l, m, s);
                ++n_nodes;
            }
            while (bvh2_lane_has_leaf(l)) {
                bvh2_lane_triangle_step<kMode>(l, m, s);
                ++n_tris;
            }
        }
    }
    hit = bvh2_lane_hit(l, m);
    if (counters) {
        counters->nodes = n_nodes;
        counters->triangles = n_tris;
    }
    return l.status;
}

}  // namespace cwbvh
