// Ray versus the eight quantized child boxes of one CWBVH node
// (Ylitie, Karras, Laine 2017, section 3.1 and the traversal pseudocode),
// made conservative in the manner of Ize 2013, "Robust BVH Ray Traversal".
//
// Contract (tested in tests/traverse/node_intersect_test.cpp): for a traceable
// ray (ray.h), if the exact segment {org + t*dir : tmin <= t <= tmax, |t| < 2^128}
// touches the closed box a slot decodes to (node_decode.h, decode_plane), that slot's
// bits are set in the returned hit mask. (A hit whose t rounds beyond the float range is
// no hit, spec/rays.md.) Extra bits (false positives) are allowed; they cost a little time and
// never change a result.
//
// Two implementations of the same arithmetic:
//   intersect_node_scalar: device code and hosts without SSE2. Register-only: the
//     quantized planes are read as 32-bit words and the octant picks near/far words
//     with an integer select (a run-time choice between q_lo/q_hi row pointers
//     forced the whole node into local memory on the GPU).
//   intersect_node_sse:    x86-64 host code (SSE2 is baseline there). All eight
//     slots at once in two 4-lane vectors.
// Both perform the same IEEE operations in the same order on every slot, so their
// tnear/tfar values are bit-identical (up to the sign of a zero from min/max, which
// the <= comparison cannot see) and so are their hit masks; node_intersect_test
// checks that on random nodes. intersect_node picks one at compile time.
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/kernels/axis_range.h"
#include "cwbvh/kernels/fp.h"
#include "cwbvh/kernels/ray.h"

#if defined(__SSE2__) && !defined(__CUDACC__)
#include <emmintrin.h>
#define CWBVH_NODE_SSE 1
#else
#define CWBVH_NODE_SSE 0
#endif

namespace cwbvh {

/// Per-ray state for node tests, computed once per ray.
struct NodeRay {
    float org[3];
    float org_pad;       ///< 0: lets host SIMD code load org as four lanes
    float rcp[3];        ///< RN(1/dir): +-inf for dir = +-0 and for |dir| < ~2^-128
    float rcp_pad;       ///< 0 (same reason; a garbage lane could be a slow subnormal)
    uint32_t octinv;     ///< 7 - octant; octant bit 2 = x<0, bit 1 = y<0, bit 0 = z<0
    /// Bit a (0-2) set: dir[a] == +-0 (no fast test for such a ray). Bit 4 + a
    /// (kOpenShift): axis a has no reach (tmin < 0 and d != 0: the segment extends on
    /// both sides of the origin; axis_range.h). Bit 31 (kFastBit): this ray uses
    /// intersect_node_fast (enable_fast_node_test; only rays without zero axes do). One
    /// register for all on the GPU.
    uint32_t zero_axes;
    static constexpr uint32_t kFastBit = 0x80000000u;
    static constexpr int kOpenShift = 4;
    CWBVH_HD bool uses_fast_test() const { return (zero_axes & kFastBit) != 0; }
    CWBVH_HD uint32_t zero_axis_bits() const { return zero_axes & 7u; }
    /// Axes (bit a) on which reach[a] bounds the segment.
    CWBVH_HD uint32_t reach_axis_bits() const { return ~(zero_axes >> kOpenShift) & 7u; }
    /// Per axis: all ones when dir[a] < 0 (near plane = q_hi), else 0. Host SIMD
    /// code swaps the q_lo/q_hi plane words with it; device code derives it from octinv.
    uint64_t swap[3];
    /// One set of three registers, two uses (the kernels hold NodeRay in registers, and a
    /// ray takes one node test or the other throughout):
    union {
        /// Reference test (kFastBit clear): the segment's reach per axis (axis_range.h),
        /// for the axes whose slab arithmetic gives up in a node (axis_range_filter).
        /// From make_node_ray.
        float reach[3];
        /// Fast test (kFastBit set; node_intersect_fast.h): -RN(o' * rcp) per axis.
        /// Written by enable_fast_node_test only when it sets kFastBit, so clearing the
        /// bit afterwards does not bring `reach` back: make the NodeRay again instead.
        float norcp[3];
    };
    /// For intersect_node_fast: the node frame's ray part, (243 - r) << 23 with
    /// r = floor(log2 max|rcp|) (enable_fast_node_test; 0 from make_node_ray).
    uint32_t frame;
};

CWBVH_HD CWBVH_INLINE NodeRay make_node_ray(const Ray& r) {
    NodeRay n;
    uint32_t octant = 0;
    n.zero_axes = 0;
    n.org_pad = 0.0f;
    n.rcp_pad = 0.0f;
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
        n.swap[a] = r.dir[a] < 0.0f ? ~uint64_t(0) : uint64_t(0);
        if (r.tmin < 0.0f && r.dir[a] != 0.0f) n.zero_axes |= 1u << (NodeRay::kOpenShift + a);
    }
    segment_reaches(r.org, r.dir, r.tmax, n.reach);
    n.octinv = 7u - octant;
    n.frame = 0u;
    return n;
}

/// Relative bound on the error of one slab distance, see intersect_node.
/// 2^-20 = 16 units of roundoff u = 2^-24; the derivation needs a bit over 5u.
inline constexpr float kSlabErrorScale = 9.5367431640625e-07f;  // 2^-20
/// Per node-axis limit on the slab terms. Below it, no slab distance overflows.
inline constexpr float kSlabBound = 8.5070591730234616e+37f;  // 2^126

// Slab arithmetic (both implementations). Paper form: t(q) = q * adj_idir + adj_orig
// per plane, with
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
// coordinates) gets no slab culling: adj_idir = 0, near = -inf, far = +inf.
// That is conservative, and it keeps inf*0 and inf-inf (NaN) out of the loop:
// with no NaN anywhere, min/max are exact up to the sign of a zero result.
// Such axes are culled afterwards by the range between the origin and the segment's
// reach (axis_range_filter; for d == +-0 the exact "origin inside the slab" test).

/// Byte `s` (0..7) of the eight-byte plane row held in the words w0 (slots 0..3),
/// w1 (slots 4..7), as a float (exact: 0..255).
CWBVH_HD CWBVH_INLINE float plane_byte(uint32_t w0, uint32_t w1, int s) {
#ifdef __CUDA_ARCH__
    // The byte into the low mantissa bits of 2^23 (one PRMT), minus 2^23: the
    // same exact value (the subtraction is exact), without the integer->float
    // conversion unit, whose low throughput bounded the node step: H100, all
    // catalog views, 2048x2048: CWBVH +12% primary, +8% diffuse bounce 1
    // (bench/results/gpu/2026-11-25-h100/plane-byte.md).
    return __uint_as_float(__byte_perm(s < 4 ? w0 : w1, 0x4B000000u, 0x7440u | uint32_t(s & 3))) - 8388608.0f;
#else
    return float(((s < 4 ? w0 : w1) >> (8 * (s & 3))) & 0xFFu);
#endif
}

/// The culling of the axes whose slab arithmetic gives up in this node (axes: bit a;
/// d = +-0, or slab terms unbounded: tiny or huge |d|, huge coordinates): clears the bits
/// of slots whose decoded [lo, hi] on such an axis misses the range between the origin and
/// the segment's reach there (axis_range.h; for d = +-0 the exact "origin inside the slab"
/// test). Rare: called only when some axis of the node is unbounded. slots: bit s = slot
/// s. The ray must use the reference test (r.reach is read).
CWBVH_HD CWBVH_INLINE uint32_t axis_range_filter(const CwbvhNode& n, const NodeRay& r, uint32_t axes,
                                                 uint32_t slots) {
    uint32_t lo_w[6], hi_w[6];
    memcpy(lo_w, n.q_lo, sizeof lo_w);
    memcpy(hi_w, n.q_hi, sizeof hi_w);
    // One axis at a time, its words picked by selects (no register array indexed by a
    // run-time value): one copy of the slot loop in the code, not three.
    CWBVH_NO_UNROLL
    for (int a = 0; a < 3; ++a) {
        if (((axes >> a) & 1u) == 0) continue;
        const bool x = a == 0, y = a == 1;
        const uint32_t l0 = x ? lo_w[0] : y ? lo_w[2] : lo_w[4], l1 = x ? lo_w[1] : y ? lo_w[3] : lo_w[5];
        const uint32_t h0 = x ? hi_w[0] : y ? hi_w[2] : hi_w[4], h1 = x ? hi_w[1] : y ? hi_w[3] : hi_w[5];
        const float p = x ? n.p[0] : y ? n.p[1] : n.p[2];
        const uint8_t e = x ? n.e[0] : y ? n.e[1] : n.e[2];
        const float o = x ? r.org[0] : y ? r.org[1] : r.org[2];
        const float reach = x ? r.reach[0] : y ? r.reach[1] : r.reach[2];
        CWBVH_UNROLL
        for (int s = 0; s < kWidth; ++s) {
            const float lo = decode_plane_qf(p, e, plane_byte(l0, l1, s));
            const float hi = decode_plane_qf(p, e, plane_byte(h0, h1, s));
            slots &= reach_meets(o, reach, lo, hi) ? ~0u : ~(1u << s);
        }
    }
    return slots;
}

/// Meta byte decode (paper; cwbvh-facts 1.2) of the slots in `slots` (bit s = slot
/// s): bit 4 of meta & (meta << 1) is set exactly when the low five bits are >= 24,
/// i.e. for an internal child, whose low bits 24 + s become 24 + (s ^ octinv); a leaf
/// keeps its triangle offset. The top three bits are 1 for an internal child and the
/// unary triangle count for a leaf, so one shift sets one node bit or up to three
/// triangle bits; an empty slot (meta 0) sets none, so `slots` may include empty ones.
/// Four slots per word, byte-parallel: no carry crosses a byte (bit 4 of m & (m << 1)
/// comes from bits 3 and 4 of the same byte, and each byte of `inner` is 0 or 1 before
/// the multiplication by 0x1F). meta_w: the node's eight meta bytes as two words.
CWBVH_HD CWBVH_INLINE uint32_t meta_hit_bits(const uint32_t meta_w[2], uint32_t octinv, uint32_t slots) {
    uint32_t bits_w[2], index_w[2];
    const uint32_t octinv4 = octinv * 0x01010101u;
    CWBVH_UNROLL
    for (int h = 0; h < 2; ++h) {
        const uint32_t m = meta_w[h];
        const uint32_t inner = ((m & (m << 1)) >> 4) & 0x01010101u;
        index_w[h] = (m ^ (octinv4 & (inner * 0x1Fu))) & 0x1F1F1F1Fu;
        bits_w[h] = (m >> 5) & 0x07070707u;
    }
    uint32_t hitmask = 0;
    CWBVH_UNROLL
    for (int s = 0; s < kWidth; ++s) {
        const uint32_t bits = (bits_w[s >> 2] >> (8 * (s & 3))) & 0x7u;
        const uint32_t index = (index_w[s >> 2] >> (8 * (s & 3))) & 0x1Fu;
        hitmask |= (((slots >> s) & 1u) ? bits : 0u) << index;
    }
    return hitmask;
}

/// Hit mask of a node in the paper's layout: for each slot s whose box the ray
/// may touch, internal children set bit 24 + (s ^ octinv); leaf children set
/// their triangles' bits (meta offset .. offset+count-1). tmin/tmax: the ray's
/// current interval (tmax shrinks as closer hits are found).
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_scalar(const CwbvhNode& n, const NodeRay& r, float tmin,
                                                     float tmax) {
    // Plane rows as words: row a of q_lo is lo_w[2a] (slots 0..3), lo_w[2a+1] (4..7).
    uint32_t lo_w[6], hi_w[6], meta_w[2];
    memcpy(lo_w, n.q_lo, sizeof lo_w);
    memcpy(hi_w, n.q_hi, sizeof hi_w);
    memcpy(meta_w, n.meta, sizeof meta_w);
    float adj_idir[3], orig_near[3], orig_far[3];
    uint32_t near_w[6], far_w[6];
    uint32_t unbounded = 0;  // bit a: no slab culling on axis a in this node
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
        const float idir = mul_rn(exponent_scale(n.e[a]), r.rcp[a]);
        const float orig = mul_rn(sub_rn(n.p[a], r.org[a]), r.rcp[a]);
        const float s = 255.0f * abs_f(idir) + abs_f(orig) + abs_f(mul_rn(n.p[a], r.rcp[a]));
        const bool bounded = s < kSlabBound;  // false for inf and NaN
        unbounded |= bounded ? 0u : 1u << a;
        const float err = s * kSlabErrorScale + kFloatMin;
        adj_idir[a] = bounded ? idir : 0.0f;
        orig_near[a] = bounded ? sub_rn(orig, err) : -kInfinity;  // rounds down enough: see above
        orig_far[a] = bounded ? add_rn(orig, err) : kInfinity;    // rounds up enough: see above
        // Octant swap: for d < 0 the near plane is the upper one (a select on words).
        const bool neg = (r.octinv & (4u >> a)) == 0;
        CWBVH_UNROLL
        for (int h = 0; h < 2; ++h) {
            near_w[2 * a + h] = neg ? hi_w[2 * a + h] : lo_w[2 * a + h];
            far_w[2 * a + h] = neg ? lo_w[2 * a + h] : hi_w[2 * a + h];
        }
    }

    uint32_t slots = 0;  // bit s: slot s is non-empty and its box may be touched
    CWBVH_UNROLL
    for (int s = 0; s < kWidth; ++s) {
        // q * adj_idir + orig: contraction to an fma is allowed (it only removes a rounding).
        const float tnx = plane_byte(near_w[0], near_w[1], s) * adj_idir[0] + orig_near[0];
        const float tny = plane_byte(near_w[2], near_w[3], s) * adj_idir[1] + orig_near[1];
        const float tnz = plane_byte(near_w[4], near_w[5], s) * adj_idir[2] + orig_near[2];
        const float tfx = plane_byte(far_w[0], far_w[1], s) * adj_idir[0] + orig_far[0];
        const float tfy = plane_byte(far_w[2], far_w[3], s) * adj_idir[1] + orig_far[1];
        const float tfz = plane_byte(far_w[4], far_w[5], s) * adj_idir[2] + orig_far[2];
        const float tnear = max_f(max_f(tnx, tny), max_f(tnz, tmin));
        const float tfar = min_f(min_f(tfx, tfy), min_f(tfz, tmax));
        // Empty slots need no test here: their meta byte is 0, so they add no bits below.
        slots |= uint32_t(tnear <= tfar) << s;
    }
    unbounded &= r.reach_axis_bits();
    if (unbounded != 0 && slots != 0) slots = axis_range_filter(n, r, unbounded, slots);
    return meta_hit_bits(meta_w, r.octinv, slots);
}

#if CWBVH_NODE_SSE
/// intersect_node_scalar on 2 x 4 lanes (see the file comment).
inline uint32_t intersect_node_sse(const CwbvhNode& n, const NodeRay& r, float tmin, float tmax) {
    const __m128i zero = _mm_setzero_si128();
    const __m128 xyz = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
    // Per-axis setup in lanes x, y, z (lane 3 is 0 throughout: no subnormal, no NaN).
    const __m128 p = _mm_and_ps(_mm_loadu_ps(n.p), xyz);  // lane 3 would be e[] and imask
    uint32_t e_word;
    memcpy(&e_word, n.e, sizeof e_word);  // e[0], e[1], e[2], imask
    __m128i e = _mm_unpacklo_epi16(_mm_unpacklo_epi8(_mm_cvtsi32_si128(int(e_word)), zero), zero);
    const __m128 scale = _mm_and_ps(_mm_castsi128_ps(_mm_slli_epi32(e, 23)), xyz);  // exponent_scale
    const __m128 org = _mm_loadu_ps(r.org);  // org_pad = 0
    const __m128 rcp = _mm_loadu_ps(r.rcp);  // rcp_pad = 0
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7FFFFFFF));
    const __m128 idir = _mm_mul_ps(scale, rcp);
    const __m128 orig = _mm_mul_ps(_mm_sub_ps(p, org), rcp);
    const __m128 sum = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(255.0f), _mm_and_ps(idir, abs_mask)),
                                           _mm_and_ps(orig, abs_mask)),
                                _mm_and_ps(_mm_mul_ps(p, rcp), abs_mask));
    const __m128 bounded = _mm_cmplt_ps(sum, _mm_set1_ps(kSlabBound));  // false for inf and NaN
    const __m128 err = _mm_add_ps(_mm_mul_ps(sum, _mm_set1_ps(kSlabErrorScale)), _mm_set1_ps(kFloatMin));
    const __m128 adj = _mm_and_ps(bounded, idir);
    const __m128 on = _mm_or_ps(_mm_and_ps(bounded, _mm_sub_ps(orig, err)),
                                _mm_andnot_ps(bounded, _mm_set1_ps(-kInfinity)));
    const __m128 of = _mm_or_ps(_mm_and_ps(bounded, _mm_add_ps(orig, err)),
                                _mm_andnot_ps(bounded, _mm_set1_ps(kInfinity)));

    __m128 tn0 = _mm_set1_ps(tmin), tn1 = tn0;
    __m128 tf0 = _mm_set1_ps(tmax), tf1 = tf0;
    auto axis = [&](int a, __m128 adj_a, __m128 on_a, __m128 of_a) {
        const __m128i lo = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(n.q_lo[a]));
        const __m128i hi = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(n.q_hi[a]));
        const __m128i x = _mm_and_si128(_mm_xor_si128(lo, hi), _mm_loadl_epi64(reinterpret_cast<const __m128i*>(&r.swap[a])));
        const __m128i qn = _mm_unpacklo_epi8(_mm_xor_si128(lo, x), zero);
        const __m128i qf = _mm_unpacklo_epi8(_mm_xor_si128(hi, x), zero);
        const __m128 qn0 = _mm_cvtepi32_ps(_mm_unpacklo_epi16(qn, zero));
        const __m128 qn1 = _mm_cvtepi32_ps(_mm_unpackhi_epi16(qn, zero));
        const __m128 qf0 = _mm_cvtepi32_ps(_mm_unpacklo_epi16(qf, zero));
        const __m128 qf1 = _mm_cvtepi32_ps(_mm_unpackhi_epi16(qf, zero));
        tn0 = _mm_max_ps(tn0, _mm_add_ps(_mm_mul_ps(qn0, adj_a), on_a));
        tn1 = _mm_max_ps(tn1, _mm_add_ps(_mm_mul_ps(qn1, adj_a), on_a));
        tf0 = _mm_min_ps(tf0, _mm_add_ps(_mm_mul_ps(qf0, adj_a), of_a));
        tf1 = _mm_min_ps(tf1, _mm_add_ps(_mm_mul_ps(qf1, adj_a), of_a));
    };
    axis(0, _mm_shuffle_ps(adj, adj, 0x00), _mm_shuffle_ps(on, on, 0x00), _mm_shuffle_ps(of, of, 0x00));
    axis(1, _mm_shuffle_ps(adj, adj, 0x55), _mm_shuffle_ps(on, on, 0x55), _mm_shuffle_ps(of, of, 0x55));
    axis(2, _mm_shuffle_ps(adj, adj, 0xAA), _mm_shuffle_ps(on, on, 0xAA), _mm_shuffle_ps(of, of, 0xAA));
    const uint32_t box_hits = uint32_t(_mm_movemask_ps(_mm_cmple_ps(tn0, tf0))) |
                              (uint32_t(_mm_movemask_ps(_mm_cmple_ps(tn1, tf1))) << 4);
    uint32_t slots = box_hits;
    const uint32_t unbounded = ~uint32_t(_mm_movemask_ps(bounded)) & r.reach_axis_bits();
    if (unbounded != 0 && slots != 0) slots = axis_range_filter(n, r, unbounded, slots);
    uint32_t meta_w[2];
    memcpy(meta_w, n.meta, sizeof meta_w);
    return meta_hit_bits(meta_w, r.octinv, slots);
}
#endif

CWBVH_HD CWBVH_INLINE uint32_t intersect_node(const CwbvhNode& n, const NodeRay& r, float tmin, float tmax) {
#if CWBVH_NODE_SSE
    return intersect_node_sse(n, r, tmin, tmax);
#else
    return intersect_node_scalar(n, r, tmin, tmax);
#endif
}

}  // namespace cwbvh
