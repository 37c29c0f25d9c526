// The GPU's common-path node test: the eight quantized child boxes of a CWBVH node
// in about 60% of the instructions of intersect_node_scalar, for rays and scenes that
// meet the conditions of fast_node_test_applies (checked once per ray, at set-up;
// every other ray takes intersect_node_scalar, node by node). Issue 18: on Hopper the
// traversal is bound by issued instructions, not by memory.
//
// Contract: as intersect_node (node_intersect.h): a slot whose decoded box the exact
// segment [tmin, tmax] touches has its bits set; extra bits are allowed. The host
// builds the same function (intrinsics emulated bit for bit), so that
// tests/traverse/node_intersect_test.cpp checks the contract on random nodes and rays
// and the CPU warp model runs what the kernel runs.
//
// What is cheaper than intersect_node_scalar, and why it stays conservative:
//  1. Plane bytes become floats with one byte permute and no subtraction: the byte
//     q goes into mantissa bits 8..15 of 1.0f, giving F = 1 + q 2^-15 exactly. The
//     slab distance q idir + O is then F J + O' with J = 2^15 idir (exact: a power of
//     two times RN(1/d), a normal float on this path) and O' = RN(O - J). The extra
//     rounding in O' errs by at most u (|O| + |J|), which the bound below covers (it
//     costs 1/32 of a quantization step of slack).
//  2. Distances are measured from tmin: the set-up moves the origin to
//     o' = RN(o + tmin d) and keeps norcp = -RN(o' rcp), so O = RN(p rcp + norcp) is
//     one fma per axis and the interval starts at t' = 0. The rounding of o' moves
//     every distance by at most u |o' rcp| = u |norcp|, which S below contains.
//  3. The per-slot ends are combined by three-input integer max/min (sm_90 DPX: one
//     instruction each) on the float bit patterns. Near: max(0, tn_x, tn_y, tn_z) in
//     one __vimax3_s32_relu: with 0 in the set the result is >= +0, and non-negative
//     floats order as their bits do, while every negative float is a negative integer
//     and can never be the maximum; so it equals the float maximum. Far: the integer
//     minimum equals the float minimum when that is >= +0; when some far distance is
//     negative, the integer minimum is a negative float too (possibly nearer to zero
//     than the float minimum) and the float comparison with the near end (>= +0)
//     rejects it, except -0.0 against a near end of exactly +0, which is accepted
//     (a superset: conservative). No NaN or infinity can occur on this path.
//  4. No per-node "bounded" selects and no FLT_MIN slack: the set-up proved that no
//     slab term of any node of the scene reaches 2^125 for this ray, and that J is a
//     normal float for every node (node_scale's bounds), so S >= |J| >= 2^-126: the
//     margin E - 5u S >= 11u S >= 11 * 2^-150 covers the few roundings that may land in
//     the subnormal range (absolute error <= 2^-150 each, at most four on a path).
//
// Error bound (u = 2^-24; node_intersect.h's argument with J, O' and o'). Let T' be
// the exact distance, measured from tmin, to the decoded plane P = RN(p + 2^e q).
// Every rounding above is one relative u; summing them:
//   |t' - T'| <= u (5|O| + 3 * 255|idir| + 3|o' rcp| + |J|) <= 5u * S,
//   S = (1 + 2^-5)|J| + |O| + |norcp|   (3 * 255 / 2^15 < 2^-5).
// Near/far distances are widened by E = 2^-20 S (16u S: margin for the roundings of
// S and of O' -/+ E), near down, far up; the hit test is near <= far (closed boxes
// stay hittable). The near end is also compared with tmax itself, not with the exact
// end of the moved interval, tmax - tmin <= tmax (tmin >= 0): a superset, equal for
// the usual tmin = 0, and no rounding to direct.
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/fp.h"
#include "cwbvh/kernels/node_intersect.h"

namespace cwbvh {

/// Scene constants of the fast node test, from NODE once at upload (node_scale).
struct NodeScale {
    float plane_max;  ///< >= max over nodes and axes of |p| + 255 * 2^(e-127) (rounded up)
    float scale_max;  ///< >= max over nodes and axes of 2^(e-127)
    float rcp_floor;  ///< 2^(-14 - min e): |rcp| >= this keeps every J = 2^(e-112) rcp a normal float
    uint32_t usable;  ///< 1 when every exponent is in 1..kFastMaxExponent and both bounds are finite;
                      ///< 0 (NodeScale{}): no fast test (the CPU reference, no scene constants)
    /// 0x3F800000, the bits of 1.0f (node_scale sets it). The kernel passes it from its
    /// launch parameters to intersect_node_fast: a value the compiler cannot see keeps the
    /// byte permutes' selectors immediate (see plane_unit).
    uint32_t one_bits;
};

/// Largest biased exponent the fast test accepts: 2^15 * 2^(e-127) must stay a
/// normal float, and the exponent of J is formed as e + 15 in an integer add.
inline constexpr uint32_t kFastMaxExponent = 239;
/// Slab terms stay below this for every node (set-up check); 2^125 leaves a factor 2
/// for the widening and the final sums before any overflow.
inline constexpr float kFastSlabLimit = 4.2535295865117308e+37f;  // 2^125


// --- intrinsics, emulated on the host with the device's exact semantics ---------

/// __byte_perm(x, y, s) (default mode: each selector nibble picks one of the eight
/// bytes of y:x; only the low three bits of a nibble are used here).
CWBVH_HD CWBVH_INLINE uint32_t byte_perm(uint32_t x, uint32_t y, uint32_t s) {
#if defined(__CUDA_ARCH__)
    return __byte_perm(x, y, s);
#else
    const uint64_t v = (uint64_t(y) << 32) | x;
    uint32_t r = 0;
    for (int i = 0; i < 4; ++i) r |= uint32_t((v >> (8 * ((s >> (4 * i)) & 7u))) & 0xFFu) << (8 * i);
    return r;
#endif
}
/// Signed three-input maximum / minimum (sm_90 DPX: one instruction).
CWBVH_HD CWBVH_INLINE int32_t imax3(int32_t a, int32_t b, int32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimax3_s32(a, b, c);
#else
    const int32_t m = a > b ? a : b;
    return m > c ? m : c;
#endif
}
/// max(0, a, b, c) (sm_90 DPX: one instruction).
CWBVH_HD CWBVH_INLINE int32_t imax3_relu(int32_t a, int32_t b, int32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimax3_s32_relu(a, b, c);
#else
    const int32_t m = imax3(a, b, c);
    return m > 0 ? m : 0;
#endif
}
CWBVH_HD CWBVH_INLINE int32_t imin3(int32_t a, int32_t b, int32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimin3_s32(a, b, c);
#else
    const int32_t m = a < b ? a : b;
    return m < c ? m : c;
#endif
}
/// b << (c & 31) as the funnel shift __funnelshift_l(0, b, c).
CWBVH_HD CWBVH_INLINE uint32_t shl_wrap(uint32_t b, uint32_t c) {
#if defined(__CUDA_ARCH__)
    return __funnelshift_l(0u, b, c);
#else
    return b << (c & 31u);
#endif
}
CWBVH_HD CWBVH_INLINE int32_t float_as_int(float f) { return int32_t(float_to_bits(f)); }

/// F = 1 + q 2^-15 for byte s (0..3) of w: bytes (0x00, q, 0x80, 0x3F). `one` is
/// the bit pattern of 1.0f from an operand the compiler cannot fold (the kernel's launch
/// parameter NodeScale::one_bits, in the constant bank): with the constant in the
/// instruction, the byte permute would need its selector in a register, and nvcc
/// rematerializes the four selectors before nearly every permute (+37 SASS
/// instructions per node step).
CWBVH_HD CWBVH_INLINE float plane_unit(uint32_t w, int s, uint32_t one) {
    return bits_to_float(byte_perm(w, one, 0x7604u | (uint32_t(s & 3) << 4)));
}

/// Whether the fast test is exact enough for this ray in this scene: tmin finite and
/// >= +0 (bit pattern: -0 does not pass, callers make it +0 first), every rcp finite
/// and |rcp| >= rcp_floor (every J normal), and
/// (2^16 scale_max + plane_max + 2|o'|max) |rcp|max < 2^125, which bounds every slab
/// term S of every node: S <= (1.04 * 2^15 * 2^(e-127) + |p| + 2|o'|)(1 + 3u) |rcp|,
/// and |p| + 255 * 2^(e-127) <= plane_max covers |p|. o': the moved origin.
CWBVH_HD CWBVH_INLINE bool fast_node_test_applies(const NodeScale& sc, const float org_moved[3], const float rcp[3],
                                                  float tmin) {
    if (sc.usable == 0 || float_as_int(tmin) < 0 || !(tmin < kInfinity)) return false;
    float rmax = 0.0f, omax = 0.0f;
    for (int a = 0; a < 3; ++a) {
        const float ar = abs_fm(rcp[a]);
        if (!(ar >= sc.rcp_floor && ar < kInfinity)) return false;  // also NaN
        rmax = ar > rmax ? ar : rmax;
        const float ao = abs_fm(org_moved[a]);
        if (!(ao < kInfinity)) return false;
        omax = ao > omax ? ao : omax;
    }
    // Each sum and product below rounds to nearest (relative error <= u); the factor
    // 2 between 2^125 and the 2^126 the analysis needs absorbs them.
    const float reach = 65536.0f * sc.scale_max + sc.plane_max + 2.0f * omax;
    return reach * rmax < kFastSlabLimit;
}

/// Lets `r` use intersect_node_fast when fast_node_test_applies: moves the origin to
/// o' = RN(o + tmin d) for norcp (dir: the ray's direction; tmin: the lane's, already
/// +0 for a -0 tmin). The scalar test keeps using org.
CWBVH_HD CWBVH_INLINE void enable_fast_node_test(NodeRay& r, const NodeScale& sc, const float dir[3], float tmin) {
    float moved[3];
    for (int a = 0; a < 3; ++a) {
        moved[a] = fma_rn(tmin, dir[a], r.org[a]);
        r.norcp[a] = -mul_rn(moved[a], r.rcp[a]);
    }
    const bool fast = r.zero_axis_bits() == 0 && fast_node_test_applies(sc, moved, r.rcp, tmin);
    r.zero_axes = r.zero_axis_bits() | (fast ? NodeRay::kFastBit : 0u);
}

/// A CwbvhNode as the twenty 32-bit words a GPU loads (five 16-byte loads): the fast
/// test and the kernels' group decode read these words and never the node's bytes.
/// Why not the CwbvhNode itself: where a kernel holds one loaded node for both node
/// tests (intersect_node_dispatch), nvcc splits the struct into its bytes for the
/// reference arithmetic and then rebuilds every word the fast test reads from them
/// (six instructions per word, about 80 per node step on sm_90, issue 18).
/// Words (the layout of spec 3.3): 0-2 p, 3 e[0..2] | imask << 24, 4 child_base,
/// 5 tri_base, 6-7 meta, 8-13 q_lo (x slots 0-3, x 4-7, y, z), 14-19 q_hi.
struct NodeWords {
    uint32_t w[20];
};
static_assert(sizeof(NodeWords) == sizeof(CwbvhNode), "NodeWords is CwbvhNode's 80 bytes");

/// Node `p` as words: on the device five 16-byte loads through the read-only cache,
/// so `p` must be 16-byte aligned there (DeviceScene's NODE and TLAS are cudaMalloc'd
/// arrays of 80-byte records; a caller's own device copy of a section needs the same);
/// on the host a copy.
CWBVH_HD CWBVH_INLINE NodeWords load_node_words(const CwbvhNode* p) {
    NodeWords n;
#if defined(__CUDA_ARCH__)
    const uint4* q = reinterpret_cast<const uint4*>(p);
    CWBVH_UNROLL
    for (int i = 0; i < 5; ++i) {
        const uint4 v = __ldg(q + i);
        n.w[4 * i + 0] = v.x;
        n.w[4 * i + 1] = v.y;
        n.w[4 * i + 2] = v.z;
        n.w[4 * i + 3] = v.w;
    }
#else
    memcpy(&n, p, sizeof n);
#endif
    return n;
}
CWBVH_HD CWBVH_INLINE NodeWords node_words(const CwbvhNode& n) {
    NodeWords w;
    memcpy(&w, &n, sizeof w);
    return w;
}
CWBVH_HD CWBVH_INLINE CwbvhNode node_from_words(const NodeWords& w) {
    CwbvhNode n;
    memcpy(&n, &w, sizeof n);
    return n;
}
/// The group fields (traverse.h's node step), from either form of a node.
CWBVH_HD CWBVH_INLINE uint32_t node_child_base(const CwbvhNode& n) { return n.child_base; }
CWBVH_HD CWBVH_INLINE uint32_t node_tri_base(const CwbvhNode& n) { return n.tri_base; }
CWBVH_HD CWBVH_INLINE uint32_t node_imask(const CwbvhNode& n) { return n.imask; }
CWBVH_HD CWBVH_INLINE uint32_t node_child_base(const NodeWords& n) { return n.w[4]; }
CWBVH_HD CWBVH_INLINE uint32_t node_tri_base(const NodeWords& n) { return n.w[5]; }
CWBVH_HD CWBVH_INLINE uint32_t node_imask(const NodeWords& n) { return n.w[3] >> 24; }

/// The fast node test (see the file comment). octinv and the plane rows as in
/// intersect_node_scalar; tmin is in the moved origin (enable_fast_node_test). one: the
/// scene's NodeScale::one_bits, the bits of 1.0f from somewhere the compiler cannot see
/// through (see plane_unit): the kernel passes its launch parameter, in the constant bank,
/// which takes no register.
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_fast(const NodeWords& n, const NodeRay& r, float tmax, uint32_t one) {
    const uint32_t* lo_w = n.w + 8;
    const uint32_t* hi_w = n.w + 14;
    const uint32_t* meta_w = n.w + 6;
    const uint32_t e_w = n.w[3];
    float J[3], on[3], of[3];
    uint32_t near_w[6], far_w[6];
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
        // 2^15 * 2^(e-127) as bits: (e + 15) << 23 (e <= kFastMaxExponent: no carry out).
        // Not masked to e's byte: of the word's higher bits only the next one stays in the
        // shifted word, as the sign bit, and J takes the magnitude (a free |.| on the
        // multiply): three masks less per node (issue 18).
        const float scale = bits_to_float((e_w >> (8 * a)) * 0x00800000u + (15u << 23));
        J[a] = mul_rn(abs_fm(scale), r.rcp[a]);                          // exact
        const float O = fma_rn(bits_to_float(n.w[a]), r.rcp[a], r.norcp[a]);  // RN(p rcp - RN(o' rcp))
        const float Op = sub_rn(O, J[a]);                                 // RN(O - J)
        const float S = fma_rn(1.03125f, abs_fm(J[a]), add_rn(abs_fm(O), abs_fm(r.norcp[a])));
        on[a] = fma_rn(S, -9.5367431640625e-07f, Op);  // O' - 2^-20 S
        of[a] = fma_rn(S, 9.5367431640625e-07f, Op);   // O' + 2^-20 S
        const bool neg = (r.octinv & (4u >> a)) == 0;
        CWBVH_UNROLL
        for (int h = 0; h < 2; ++h) {
            near_w[2 * a + h] = neg ? hi_w[2 * a + h] : lo_w[2 * a + h];
            far_w[2 * a + h] = neg ? lo_w[2 * a + h] : hi_w[2 * a + h];
        }
    }
    // Meta decode, four slots per word (node_intersect.h, meta_hit_bits): the bit
    // index with the octant applied to internal children (bit 4 of m & (m << 1) marks
    // them; times octinv, each byte 0 or octinv, no carries), and the unary counts.
    uint32_t index_w[2], bits_w[2];
    CWBVH_UNROLL
    for (int h = 0; h < 2; ++h) {
        const uint32_t m = meta_w[h];
        const uint32_t inner = ((m & (m << 1)) & 0x10101010u) >> 4;
        index_w[h] = m ^ (inner * r.octinv);  // low five bits of each byte
        bits_w[h] = (m >> 5) & 0x07070707u;
    }
    uint32_t hitmask = 0;
    CWBVH_UNROLL
    for (int s = 0; s < kWidth; ++s) {
        const int h = s >> 2;
        const float tnx = fma_rn(plane_unit(near_w[0 + h], s, one), J[0], on[0]);
        const float tny = fma_rn(plane_unit(near_w[2 + h], s, one), J[1], on[1]);
        const float tnz = fma_rn(plane_unit(near_w[4 + h], s, one), J[2], on[2]);
        const float tfx = fma_rn(plane_unit(far_w[0 + h], s, one), J[0], of[0]);
        const float tfy = fma_rn(plane_unit(far_w[2 + h], s, one), J[1], of[1]);
        const float tfz = fma_rn(plane_unit(far_w[4 + h], s, one), J[2], of[2]);
        const float tnear = bits_to_float(uint32_t(imax3_relu(float_as_int(tnx), float_as_int(tny), float_as_int(tnz))));
        const float tfar = bits_to_float(uint32_t(imin3(float_as_int(tfx), float_as_int(tfy), float_as_int(tfz))));
        if (tnear <= tfar && tnear <= tmax) {
            // Empty slots have meta 0: no bits.
            const uint32_t bits = byte_perm(bits_w[h], 0u, 0x4440u | uint32_t(s & 3));
            hitmask |= shl_wrap(bits, index_w[h] >> (8 * (s & 3)));
        }
    }
    return hitmask;
}

/// The fast test on a node in its struct form (the host: tests, the CPU traversal).
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_fast(const CwbvhNode& n, const NodeRay& r, float tmax, uint32_t one) {
    return intersect_node_fast(node_words(n), r, tmax, one);
}

/// The node test a traversal runs on `r`: intersect_node_fast where the ray's set-up
/// enabled it (r.uses_fast_test()) on sm_80 and later, the reference arithmetic otherwise.
/// sm_90 has the three-input integer min/max in one instruction (DPX); sm_80-89 (A100,
/// Ampere, Ada) emulate them with two-input ones and still gain: node step 295 against 377
/// by bench/gpu/step_sizes.sh sm_80, 80 registers and no spills. On sm_75 the kernels would
/// spill: reference arithmetic. On the host the flag selects too (the warp model and the
/// tests run what the kernel runs).
/// one: NodeScale::one_bits (see plane_unit). The kernels pass NodeWords (see there),
/// the host CPU traversal the node in place.
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_dispatch(const NodeWords& n, const NodeRay& r, float tmin, float tmax,
                                                       uint32_t one) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
    (void)one;
    return intersect_node(node_from_words(n), r, tmin, tmax);
#else
    if (r.uses_fast_test()) return intersect_node_fast(n, r, tmax, one);
    return intersect_node(node_from_words(n), r, tmin, tmax);
#endif
}
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_dispatch(const CwbvhNode& n, const NodeRay& r, float tmin, float tmax,
                                                       uint32_t one) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
    (void)one;
    return intersect_node(n, r, tmin, tmax);
#else
    return r.uses_fast_test() ? intersect_node_fast(n, r, tmax, one) : intersect_node(n, r, tmin, tmax);
#endif
}

#if !defined(__CUDA_ARCH__)
/// The scene constants for `count` nodes (host, once per upload: O(nodes)). Exponents
/// outside 1..kFastMaxExponent (0 decodes every plane to p, which 2^15 * 2^(e-127)
/// cannot express) make the scene use intersect_node_scalar throughout.
inline NodeScale node_scale(const CwbvhNode* nodes, uint64_t count) {
    double plane = 0.0;
    bool finite = true;
    uint32_t emin = 255, emax = 0;
    for (uint64_t i = 0; i < count; ++i) {
        for (int a = 0; a < 3; ++a) {
            const uint32_t e = nodes[i].e[a];
            emin = e < emin ? e : emin;
            emax = e > emax ? e : emax;
            const double pa = nodes[i].p[a];
            const double reach = (pa < 0 ? -pa : pa) + 255.0 * double(exponent_scale(uint8_t(e)));
            finite = finite && reach < 1e38;  // false for NaN and inf
            plane = reach > plane ? reach : plane;
        }
    }
    NodeScale sc{0.0f, 0.0f, 0.0f, 0u, 0x3F800000u};
    if (count == 0 || !finite || emin < 1 || emax > kFastMaxExponent) return sc;
    // Round up to float: the set-up test must not underestimate.
    float pf = float(plane);
    if (double(pf) < plane) pf = bits_to_float(float_to_bits(pf) + 1u);
    sc.plane_max = pf;
    sc.scale_max = exponent_scale(uint8_t(emax));
    // 2^(-14 - emin); FLT_MIN (a stronger condition) where that would be subnormal.
    sc.rcp_floor = emin <= 112 ? exponent_scale(uint8_t(127 - 14 - emin)) : kFloatMin;
    sc.usable = 1u;
    return sc;
}

/// Constants that hold for the nodes of both a and b (a two-level scene: NODE and
/// TLAS): the larger bounds and rcp floor; usable only when both are.
inline NodeScale merge_node_scale(const NodeScale& a, const NodeScale& b) {
    if (a.usable == 0 || b.usable == 0) return NodeScale{0.0f, 0.0f, 0.0f, 0u, 0x3F800000u};
    NodeScale m = a;
    m.plane_max = a.plane_max > b.plane_max ? a.plane_max : b.plane_max;
    m.scale_max = a.scale_max > b.scale_max ? a.scale_max : b.scale_max;
    m.rcp_floor = a.rcp_floor > b.rcp_floor ? a.rcp_floor : b.rcp_floor;
    return m;
}
#endif

}  // namespace cwbvh
