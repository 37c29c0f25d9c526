// Binary BVH traversal over Bvh2Node (the BVH2 and BV2L sections): the baseline
// the paper compares against (Aila & Laine 2009, "Understanding the Efficiency of
// Ray Traversal on GPUs", while-while loop; Aila, Laine, Karras 2012 node layout,
// leaf postponing and dynamic fetch). Same triangle tests and status codes as
// traverse_cwbvh. This header: the per-ray box-test set-up and the box test;
// bvh2_lane.h (included at the end): the lane steps shared by the GPU kernel and
// traverse_bvh2(), the CPU reference.
//
// Box test: t = (b - o) * RN(1/d) on float planes, widened as in Ize 2013: the
// computed t is within a relative 3u (u = 2^-24) of the exact one, so near is
// rounded DOWN by the factor (1 -/+ 2^-21) and far UP (2^-21 = 8u covers the 3u,
// the factor's own rounding and slack), then FLT_MIN of absolute slack for
// subnormals. Axes with non-finite or subnormal RN(1/d) (|d| = 0, < ~2^-128 or
// > 2^126) are unbounded: culled by the range between the origin and the segment's
// reach instead (axis_range.h; for d = +-0 the exact "origin inside" test). Hit test:
// near <= far.
//
// Stack bound: one entry per level at most (the far child), so entries < depth of
// the binary tree; a full push stops with kStackOverflow.
#pragma once

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/axis_range.h"
#include "cwbvh/kernels/fp.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

struct Bvh2Ray {
    float org[3];
    /// RN(1/d[a]); on an unbounded axis the segment's reach there instead (the slab test
    /// skips the axis and culls by the range between o and the reach, axis_range.h).
    float rcp[3];
    /// Bit a: RN(1/d[a]) is not finite, or subnormal. Bit 4 + a: and the axis is open
    /// (tmin < 0, d != 0: the segment extends on both sides of o), no culling there.
    uint32_t unbounded;
};

CWBVH_HD CWBVH_INLINE Bvh2Ray make_bvh2_ray(const Ray& r) {
    Bvh2Ray b;
    b.unbounded = 0;
    float reach[3];
    segment_reaches(r.org, r.dir, r.tmax, reach);
    for (int a = 0; a < 3; ++a) {
        b.org[a] = r.org[a];
        b.rcp[a] = 1.0f / r.dir[a];
        // Unbounded when RN(1/d) is inf (|d| tiny or 0) or subnormal (|d| > 2^126:
        // no longer within a relative u of 1/d).
        if (!is_finite_f(b.rcp[a]) || abs_f(b.rcp[a]) < kFloatMin) {
            b.unbounded |= 1u << a;
            b.rcp[a] = reach[a];
            if (r.tmin < 0.0f && r.dir[a] != 0.0f) b.unbounded |= 16u << a;
        }
    }
    return b;
}

inline constexpr float kBoxRelError = 4.76837158203125e-07f;  // 2^-21

/// Conservative slab test of the float box [lo, hi] (contract as intersect_node).
CWBVH_HD CWBVH_INLINE bool intersect_box_robust(const Bvh2Ray& r, const float* lo, const float* hi,
                                                float tmin, float tmax, float& tnear_out) {
    float tnear = tmin, tfar = tmax;
    for (int a = 0; a < 3; ++a) {
        if ((r.unbounded >> a) & 1u) {  // rare: culled by the reach (d = +-0: origin inside)
            if (((r.unbounded >> (4 + a)) & 1u) == 0 && !reach_meets(r.org[a], r.rcp[a], lo[a], hi[a])) return false;
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

}  // namespace cwbvh

// The traversal itself (lane state, node and triangle steps, and traverse_bvh2,
// the CPU reference) is in bvh2_lane.h, which needs the box test above.
#include "cwbvh/kernels/bvh2_lane.h"
