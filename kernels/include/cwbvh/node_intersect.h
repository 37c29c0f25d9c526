// Ray versus the eight quantized child boxes of one CWBVH node
// (Ylitie, Karras, Laine 2017, section 3.1 and the traversal pseudocode),
// made conservative in the manner of Ize 2013, "Robust BVH Ray Traversal".
//
// Contract (tested in tests/traverse/node_intersect_test.cpp): for a traceable
// ray (ray.h), if the exact segment {org + t*dir : tmin <= t <= tmax} touches the
// closed box a slot decodes to (node_decode.h, decode_plane), that slot's bits are
// set in the returned hit mask. Extra bits (false positives) are allowed; they
// cost a little time and never change a result.
#pragma once

#include <cstdint>

#include "cwbvh/format.h"
#include "cwbvh/fp.h"
#include "cwbvh/hostdevice.h"
#include "cwbvh/node_decode.h"
#include "cwbvh/ray.h"

namespace cwbvh {

/// Per-ray state for node tests, computed once per ray.
struct NodeRay {
    float org[3];
    float rcp[3];        ///< RN(1/dir): +-inf for dir = +-0 and for |dir| < ~2^-128
    uint32_t octinv;     ///< 7 - octant; octant bit 2 = x<0, bit 1 = y<0, bit 0 = z<0
    uint32_t zero_axes;  ///< bit a set: dir[a] == +-0 (slab test becomes "origin inside")
};

CWBVH_HD CWBVH_INLINE NodeRay make_node_ray(const Ray& r) {
    NodeRay n;
    uint32_t octant = 0;
    n.zero_axes = 0;
    for (int a = 0; a < 3; ++a) {
        n.org[a] = r.org[a];
        // Plain IEEE division: +-0 gives +-inf, a subnormal gives +-inf or a huge
        // value. Both are caught per node by the "bounded" test below, which is why
        // no "safe reciprocal" clamp (that would move the slab planes) is needed.
        n.rcp[a] = 1.0f / r.dir[a];
        // |d| > 2^126: RN(1/d) is subnormal and no longer within a relative u of 1/d.
        // Make the axis unbounded (no culling) rather than widen every node.
        if (abs_f(n.rcp[a]) < kFloatMin) n.rcp[a] = kInfinity;
        // -0 counts as positive; for a zero axis the choice does not matter
        // because that axis's slab is unbounded in t.
        if (r.dir[a] < 0.0f) octant |= 4u >> a;
        if (r.dir[a] == 0.0f) n.zero_axes |= 1u << a;
    }
    n.octinv = 7u - octant;
    return n;
}

/// Relative bound on the error of one slab distance, see intersect_node.
/// 2^-20 = 16 units of roundoff u = 2^-24; the derivation needs a bit over 5u.
inline constexpr float kSlabErrorScale = 9.5367431640625e-07f;  // 2^-20
/// Per node-axis limit on the slab terms. Below it, no slab distance overflows.
inline constexpr float kSlabBound = 8.5070591730234616e+37f;  // 2^126

/// Hit mask of a node in the paper's layout: for each slot s whose box the ray
/// may touch, internal children set bit 24 + (s ^ octinv); leaf children set
/// their triangles' bits (meta offset .. offset+count-1). tmin/tmax: the ray's
/// current interval (tmax shrinks as closer hits are found).
CWBVH_HD CWBVH_INLINE uint32_t intersect_node(const CwbvhNode& n, const NodeRay& r, float tmin,
                                              float tmax) {
    // Paper form: t(q) = q * adj_idir + adj_orig per plane, with
    //   adj_idir = 2^e / d   (exact product of a power of two and RN(1/d)),
    //   adj_orig = (p - o) / d, computed as RN(RN(p - o) * RN(1/d)).
    // Let A = 2^e q / d, B = (p - o)/d. The plane the file defines is
    // P = RN(p + 2^e q) (decode_plane), so the exact slab distance is T = (P - o)/d.
    // Error analysis (u = 2^-24, each RN a factor (1 + delta), |delta| <= u):
    //   |RN-computed t(q) - (A + B)| <= 2u|A| + 4u|B|   (mul+add or fma, either way)
    //   |T - (A + B)|               <= u|A| + u|p/d|    (rounding of P)
    // so |t - T| <= 3u|A| + 4u|B| + u|p/d| <= ~5u * S with
    //   S = 255|adj_idir| + |adj_orig| + |p * rcp|    (>= |A| , |B|, |p/d| up to 1+u).
    // We widen by E = 2^-20 * S (16u, margin for rounding of S, E and t -/+ E)
    // plus FLT_MIN (absolute slack for subnormal underflow in any product).
    // Rounding directions: the near distance must round DOWN (t - E), the far
    // distance UP (t + E); the hit test is near <= far (not <: flat boxes with
    // qlo == qhi must stay hittable, cwbvh-facts 1.9 item 4).
    // An axis whose S is >= 2^126, inf or NaN (tiny or zero |d|, or huge
    // coordinates) gets no culling at all: adj_idir = 0, near = -inf, far = +inf.
    // That is conservative, and it keeps inf*0 and inf-inf (NaN) out of the loop.
    // Axes with d == +-0 additionally get the exact "origin inside the slab" test.
    float adj_idir[3], orig_near[3], orig_far[3];
    const uint8_t* q_near[3];
    const uint8_t* q_far[3];
    for (int a = 0; a < 3; ++a) {
        const float idir = mul_rn(exponent_scale(n.e[a]), r.rcp[a]);
        const float orig = mul_rn(sub_rn(n.p[a], r.org[a]), r.rcp[a]);
        const float s = 255.0f * abs_f(idir) + abs_f(orig) + abs_f(mul_rn(n.p[a], r.rcp[a]));
        const bool bounded = s < kSlabBound;  // false for inf and NaN
        const float err = s * kSlabErrorScale + kFloatMin;
        adj_idir[a] = bounded ? idir : 0.0f;
        orig_near[a] = bounded ? sub_rn(orig, err) : -kInfinity;  // rounds down enough: see above
        orig_far[a] = bounded ? add_rn(orig, err) : kInfinity;    // rounds up enough: see above
        // Octant swap: for d < 0 the near plane is the upper one.
        const bool neg = (r.octinv & (4u >> a)) == 0;
        q_near[a] = neg ? n.q_hi[a] : n.q_lo[a];
        q_far[a] = neg ? n.q_lo[a] : n.q_hi[a];
    }

    uint32_t hitmask = 0;
    for (int s = 0; s < kWidth; ++s) {
        const uint32_t meta = n.meta[s];
        if (meta == kMetaEmpty) continue;
        // q * adj_idir + orig: contraction to an fma is allowed (it only removes a rounding).
        const float tnx = float(q_near[0][s]) * adj_idir[0] + orig_near[0];
        const float tny = float(q_near[1][s]) * adj_idir[1] + orig_near[1];
        const float tnz = float(q_near[2][s]) * adj_idir[2] + orig_near[2];
        const float tfx = float(q_far[0][s]) * adj_idir[0] + orig_far[0];
        const float tfy = float(q_far[1][s]) * adj_idir[1] + orig_far[1];
        const float tfz = float(q_far[2][s]) * adj_idir[2] + orig_far[2];
        const float tnear = max_f(max_f(tnx, tny), max_f(tnz, tmin));
        const float tfar = min_f(min_f(tfx, tfy), min_f(tfz, tmax));
        bool hit = tnear <= tfar;
        if (r.zero_axes != 0 && hit) {
            // d[a] == 0: the ray stays in the plane x_a = o_a; it touches the slab
            // iff lo <= o_a <= hi, compared exactly against the decoded planes.
            for (int a = 0; a < 3; ++a) {
                if ((r.zero_axes >> a) & 1u) {
                    const float lo = decode_plane(n.p[a], n.e[a], n.q_lo[a][s]);
                    const float hi = decode_plane(n.p[a], n.e[a], n.q_hi[a][s]);
                    hit = hit && lo <= r.org[a] && r.org[a] <= hi;
                }
            }
        }
        if (!hit) continue;
        // Meta byte decode (paper; cwbvh-facts 1.2): bit 4 of meta & (meta << 1) is set
        // exactly when the low five bits are >= 24, i.e. for an internal child, whose
        // low bits 24 + s become 24 + (s ^ octinv); a leaf keeps its triangle offset.
        // The top three bits are 1 for an internal child and the unary triangle count
        // for a leaf, so one shift sets one node bit or up to three triangle bits.
        const uint32_t is_inner = (meta & (meta << 1)) & 0x10u;
        const uint32_t inner_mask = is_inner ? 0x1Fu : 0u;
        const uint32_t bit_index = (meta ^ (r.octinv & inner_mask)) & 0x1Fu;
        const uint32_t child_bits = (meta >> 5) & 7u;
        hitmask |= child_bits << bit_index;
    }
    return hitmask;
}

}  // namespace cwbvh
