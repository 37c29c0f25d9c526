// Binary BVH traversal over Bvh2Node (the BVH2 section): the baseline the paper
// compares against (Aila & Laine 2009, "Understanding the Efficiency of Ray
// Traversal on GPUs", while-while loop; nodes in the layout of Aila, Laine, Karras
// 2012). Same triangle tests, hit semantics and status codes as traverse_cwbvh.
//
// Box test: t = (b - o) * RN(1/d) on float planes, widened as in Ize 2013: the
// computed t is within a relative 3u (u = 2^-24) of the exact one, so near is
// rounded DOWN by the factor (1 -/+ 2^-21) and far UP (2^-21 = 8u covers the 3u,
// the factor's own rounding and slack), then FLT_MIN of absolute slack for
// subnormals. Axes with non-finite RN(1/d) (|d| = 0 or < ~2^-128) are unbounded;
// exactly zero ones get the exact "origin inside" test. Hit test: near <= far.
//
// Stack bound: one entry per level at most (the far child), so entries < depth of
// the binary tree; a full push stops with kStackOverflow.
#pragma once

#include <cstdint>

#include "cwbvh/format.h"
#include "cwbvh/fp.h"
#include "cwbvh/hostdevice.h"
#include "cwbvh/ray.h"
#include "cwbvh/traverse.h"
#include "cwbvh/triangle_intersect.h"

namespace cwbvh {

struct Bvh2Ray {
    float org[3];
    float rcp[3];
    uint32_t unbounded;  ///< bit a: RN(1/d[a]) is not finite
    uint32_t zero_axes;  ///< bit a: d[a] == +-0
};

CWBVH_HD CWBVH_INLINE Bvh2Ray make_bvh2_ray(const Ray& r) {
    Bvh2Ray b;
    b.unbounded = b.zero_axes = 0;
    for (int a = 0; a < 3; ++a) {
        b.org[a] = r.org[a];
        b.rcp[a] = 1.0f / r.dir[a];
        // Unbounded when RN(1/d) is inf (|d| tiny or 0) or subnormal (|d| > 2^126:
        // no longer within a relative u of 1/d).
        if (!is_finite_f(b.rcp[a]) || abs_f(b.rcp[a]) < kFloatMin) b.unbounded |= 1u << a;
        if (r.dir[a] == 0.0f) b.zero_axes |= 1u << a;
    }
    return b;
}

inline constexpr float kBoxRelError = 4.76837158203125e-07f;  // 2^-21

/// Conservative slab test of the float box [lo, hi] (contract as intersect_node).
CWBVH_HD CWBVH_INLINE bool intersect_box_robust(const Bvh2Ray& r, const float* lo, const float* hi,
                                                float tmin, float tmax, float& tnear_out) {
    float tnear = tmin, tfar = tmax;
    for (int a = 0; a < 3; ++a) {
        if ((r.unbounded >> a) & 1u) {
            if (((r.zero_axes >> a) & 1u) && !(lo[a] <= r.org[a] && r.org[a] <= hi[a])) return false;
            continue;
        }
        float t0 = mul_rn(sub_rn(lo[a], r.org[a]), r.rcp[a]);
        float t1 = mul_rn(sub_rn(hi[a], r.org[a]), r.rcp[a]);
        if (r.rcp[a] < 0.0f) {
            const float tmp = t0;
            t0 = t1;
            t1 = tmp;
        }
        // Round near down, far up; multiplying keeps +-inf (overflow) free of inf-inf.
        t0 = sub_rn(mul_rn(t0, t0 > 0.0f ? 1.0f - kBoxRelError : 1.0f + kBoxRelError), kFloatMin);
        t1 = add_rn(mul_rn(t1, t1 > 0.0f ? 1.0f + kBoxRelError : 1.0f - kBoxRelError), kFloatMin);
        tnear = max_f(tnear, t0);
        tfar = min_f(tfar, t1);
    }
    tnear_out = tnear;
    return tnear <= tfar;
}

template <TriangleTest kTest, HitMode kMode, int kStackSize = 64>
CWBVH_HD CWBVH_INLINE TraceStatus traverse_bvh2(const Bvh2Node* nodes, uint32_t node_count,
                                                const TriangleRecord* tris, uint32_t tri_count,
                                                const Ray& ray, Hit& hit,
                                                TraceCounters* counters = nullptr) {
    hit = make_miss();
    if (!ray_is_traceable(ray) || node_count == 0) return TraceStatus::kInvalidRay;
    const Bvh2Ray bray = make_bvh2_ray(ray);
    const TriangleIntersector<kTest> tri_test(ray);
    const float tmin = ray.tmin;
    float tmax = ray.tmax;
    uint32_t n_nodes = 0, n_tris = 0;
    TraceStatus status = TraceStatus::kOk;

    constexpr int32_t kSentinel = 0x76543210;  // never a valid index (Aila & Laine's EntrypointSentinel)
    int32_t stack[kStackSize];
    int sp = 0;
    int32_t node = 0;
    bool done = false;
    while (node != kSentinel && !done) {
        // Inner loop 1: descend internal nodes.
        while (node >= 0 && node != kSentinel) {
            if (uint32_t(node) >= node_count) {
                status = TraceStatus::kBadIndex;
                done = true;
                break;
            }
            const Bvh2Node& n = nodes[node];
            ++n_nodes;
            const float lo0[3] = {n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, hi0[3] = {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z};
            const float lo1[3] = {n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, hi1[3] = {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z};
            float t0 = 0.0f, t1 = 0.0f;
            const bool h0 = intersect_box_robust(bray, lo0, hi0, tmin, tmax, t0);
            const bool h1 = intersect_box_robust(bray, lo1, hi1, tmin, tmax, t1);
            if (!h0 && !h1) {
                node = sp > 0 ? stack[--sp] : kSentinel;
            } else {
                int32_t near_child = h0 ? n.child[0] : n.child[1];
                int32_t far_child = n.child[1];
                if (h0 && h1) {
                    if (t1 < t0) {
                        near_child = n.child[1];
                        far_child = n.child[0];
                    }
                    if (sp >= kStackSize) {
                        status = TraceStatus::kStackOverflow;
                        done = true;
                        break;
                    }
                    stack[sp++] = far_child;
                }
                node = near_child;
            }
        }
        // Inner loop 2: leaves (one triangle each).
        while (!done && node < 0) {
            const uint32_t ti = uint32_t(~node);
            if (ti >= tri_count) {
                status = TraceStatus::kBadIndex;
                done = true;
                break;
            }
            ++n_tris;
            TriangleHit th;
            if (tri_test(tris[ti], tmin, tmax, th)) {
                tmax = th.t;
                hit = Hit{th.t, th.u, th.v, tris[ti].prim};
                if (kMode == HitMode::kAny) {
                    done = true;
                    break;
                }
            }
            node = sp > 0 ? stack[--sp] : kSentinel;
        }
    }
    if (counters) {
        counters->nodes = n_nodes;
        counters->triangles = n_tris;
    }
    return status;
}

}  // namespace cwbvh
