// The GPU's common-path node test: the eight quantized child boxes of a CWBVH node,
// two slots per instruction in binary16 (half) arithmetic, for rays and scenes that meet
// the conditions of fast_node_test_applies (checked once per ray, at set-up; every other
// ray takes intersect_node_scalar, node by node). Issue 18: on Hopper the traversal is
// bound by issued instructions, not by memory, and per slot the float form of this test
// (until 2026-11-27) cost 20 SASS instructions; in pairs of halves it costs about 12.
//
// Contract: as intersect_node (node_intersect.h): a slot whose decoded box the exact
// segment [tmin, tmax] touches has its bits set; extra bits are allowed. The host
// builds the same function (fp16.h emulates every half operation bit for bit), so that
// tests/traverse/node_intersect_test.cpp checks the contract on random nodes and rays
// and the CPU warp model runs what the kernel runs.
//
// The arithmetic, per node (u = 2^-24, u_h = 2^-11: float and half unit roundoffs):
//  1. A node frame. Every distance t of the node is handled as tau = f t - C: f = 2^s a
//     power of two chosen per node and ray (from the node's largest exponent e_max and
//     r = floor(log2 max|rcp|), NodeRay::frame), C >= 0 a float. With
//     s = 116 - e_max - r, the plane step of axis a in tau, Q_a = f 2^(e_a-127) |rcp_a|,
//     is J_a 2^-24 with J_a = 2^(e_a - e_max + 13 - r) |rcp_a| < 2^14 (a power of two
//     times rcp: exact unless below 2^-126), so the node's grid spans at most
//     255 * 2^-24 * 2^14 < 0.25 in tau on every axis: small values, where halves are
//     precise, at every depth.
//  2. Plane bytes become halves with one byte permute per two slots and no arithmetic:
//     the byte q goes into the low byte of a half whose high byte is zero, a subnormal
//     half of value q 2^-24, exactly. Plane q of axis a is then at tau = q 2^-24 J_a + D_a,
//     one half fma (HFMA2, two slots), with D_a = RN(f O_a - C) the distance of plane
//     q = 0 (O_a = RN(p_a rcp_a + norcp_a), as the reference test's slab terms, from the
//     moved origin o' = RN(o + tmin d)).
//  3. C is a lower bound of where the segment can enter the node's grid: the largest of
//     0 and, per axis, RD(f O_a - G_a), G_a >= the float error of f O_a plus the grid's
//     extent (either side, so no octant select): t_a <= the exact near grid plane. Every
//     point of the segment inside a child box has tau >= 0, so the near ends are clamped
//     at 0 (the relu of the DPX maximum) and nothing is lost; and for a child the segment
//     touches, every per-axis end lies within about one grid extent of [0, 0.25] plus the
//     float error: halves there carry 11 bits.
//  4. Near ends are widened down, far ends up, by E_a per axis (below), folded into D_a
//     and rounded outward twice: on_a = RD_h(RD(D_a - E_a)), of_a = RU_h(RU(D_a + E_a)),
//     so these roundings need no margin. Then near = max(0, tn_x, tn_y, tn_z) and far =
//     min(tf_x, tf_y, tf_z) per pair as DPX integer max/min on the bit patterns (as the
//     float form argued: with 0 in the maximum the integer maximum is the half maximum or
//     smaller; the integer minimum is the half minimum or a negative value, which the
//     near end >= +0 rejects exactly when the half minimum would, but for -0 against
//     +0: a touching extra), far is lowered to tmax_h = RU_h(RU(f tmax - C)), and the
//     slot is hit when near <= far (closed boxes). (tmax itself, not the moved interval's
//     exact end tmax - tmin <= tmax: a superset, equal for the usual tmin = 0.)
//
// Error bound. Against the exact distance tau* of plane q of axis a (the exact t of the
// decoded plane P = RN(p + 2^e q), measured from tmin, times f, minus C), the roundings
// to nearest:
//   float part (rcp, P, o', norcp, O rounded; f exact): <= 6u f S + 2u 2^-16 J,
//     S = |O| + |norcp|;
//   D: u|D|;
//   J to half, times q 2^-24 <= 2^-16: <= 2^-27 J (+ 2^-41 where J is subnormal);
//   the HFMA2 result, |.| <= |on_h| + 2^-16 J <= 1.001 (|D| + E) + 2^-16 J:
//     <= u_h (1.001 (|D| + E) + 2^-16 J), + 2^-25 where subnormal.
// Together <= 2^-21.4 f S + 1.002 * 2^-11 |D| + 1.001 * 2^-11 E + 1.0003 * 2^-26 J
// + 2^-24.9, and
//   E = RN(1.0625 * 2^-11 |D| + RN(1.125 * 2^-26 J + RN(2^-20 f S + 2^-23)))
// exceeds it with room for its own three roundings: after E - 1.001 * 2^-11 E, each
// term of E is still at least 1.05 times its counterpart. Overflow: f S, f O and f tmax
// stay below 2^125 for every node (set-up), J < 2^14 keeps every product q 2^-24 J below
// 0.25, and no operation can make a NaN. A half offset beyond +-65504 saturates in the
// direction it was rounded: RD of a huge near offset is 65504 (lower: conservative), RU
// of a huge negative far offset is -65504 (higher: conservative); the other two become
// infinities, which the relu and the minimum treat conservatively. Adding a product
// below 0.25 to 65504 gives 65504 again (the half spacing there is 32).
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/fp.h"
#include "cwbvh/kernels/fp16.h"
#include "cwbvh/kernels/node_intersect.h"

namespace cwbvh {

/// Scene constants of the fast node test, from NODE once at upload (node_scale).
struct NodeScale {
    float plane_max;  ///< >= max over nodes and axes of |p| + 255 * 2^(e-127) (rounded up)
    float scale_max;  ///< >= max over nodes and axes of 2^(e-127)
    uint32_t e_max;    ///< largest exponent byte over nodes and axes
    /// max(1, e_max - 100): the node frame of a node whose exponents are all below this
    /// (a degenerate node, 2^100 times smaller than the scene) is taken at e_floor, so
    /// that f = 2^(116 - e_max - r) is bounded for every node (set-up check).
    uint32_t e_floor;
    uint32_t usable;  ///< 1 when every exponent is in 1..kFastMaxExponent and both bounds are finite;
                      ///< 0 (NodeScale{}): no fast test (the CPU reference, no scene constants)
    /// e_floor << 8 (node_scale sets it). Its low byte is zero: the plane bytes' permutes
    /// take their zero byte from it. The kernel passes it from its launch parameters to
    /// intersect_node_fast: a value the compiler cannot see keeps the permutes' selectors
    /// immediate (with a literal zero, nvcc rematerializes selectors in registers before
    /// nearly every permute: +37 SASS instructions per node step in the float form).
    uint32_t frame_word;
};

/// Largest spread of the ray's |rcp| exponents, floor(log2 max|rcp|) - floor(log2 min|rcp|),
/// for which the fast test is taken (a culling limit, not an accuracy one: beyond it the
/// test stays conservative but stops culling). The node frame is scaled for the largest
/// |rcp|, so an axis whose |rcp| is 2^k times smaller has its planes 2^k times closer
/// together in tau; past about the half's 11 bits they fall within its rounding and every
/// child passes on that axis. A ray nearly parallel to a coordinate plane (one direction
/// component 10^-7 of the others: diffuse rays make them) then visits nearly every node
/// near its path: on 2026-11-28's H200 run, 1,242 nodes for a dragon diffuse ray that the
/// reference test takes through 10, 4,945 against 17 on dense_dragons, one warp holding
/// a whole launch (dragon front diffuse 2: 1.64 ms against 0.33 with the reference test;
/// the DERIVED street view's diffuse 2, 108 ms against 0.75). With spreads <= 11 the fast
/// test visits at most 11 nodes more than the reference test on any ray of dragon,
/// dense_dragons and kicad_board's worst sets (bench/results/gpu/2026-11-28-h200), and
/// 0.1 % of diffuse rays spread more (they take the reference test).
inline constexpr int kFastMaxRcpSpread = 11;

/// Largest biased exponent the fast test accepts (2^103: far beyond any scene):
/// 2^24 * 2^(e-127) must be a float, formed as (e + 24) << 23.
inline constexpr uint32_t kFastMaxExponent = 230;
/// Slab terms stay below this for every node, also times the node frame's f (set-up
/// check); 2^125 leaves a factor 2 for the widening and the final sums before any overflow.
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
/// b << (c & 31) as the funnel shift __funnelshift_l(0, b, c).
CWBVH_HD CWBVH_INLINE uint32_t shl_wrap(uint32_t b, uint32_t c) {
#if defined(__CUDA_ARCH__)
    return __funnelshift_l(0u, b, c);
#else
    return b << (c & 31u);
#endif
}
CWBVH_HD CWBVH_INLINE int32_t float_as_int(float f) { return int32_t(float_to_bits(f)); }

/// floor(log2 x) for a normal float x > 0.
CWBVH_HD CWBVH_INLINE int float_exponent(float x) { return int(float_to_bits(x) >> 23) - 127; }

/// Whether the fast test is exact enough for this ray in this scene: tmin finite and
/// >= +0 (bit pattern: -0 does not pass, callers make it +0 first), every rcp finite
/// (make_node_ray makes |rcp| >= FLT_MIN or infinite), the node frame's factor normal
/// for every node (r = floor(log2 max|rcp|); f = 2^(116 - e_max - r) and f 2^-20, with
/// e_max >= e_floor: r <= 222 - e_max, r >= -11 - e_floor over the scene),
/// the |rcp| exponents within kFastMaxRcpSpread of each other (culling, see there),
/// and every slab term bounded, also in the largest node frame:
///   (2^16 scale_max + plane_max + 2|o'|max) |rcp|max 2^(116 - e_floor - r) < 2^125
/// (S <= (1.04 * 2^15 * 2^(e-127) + |p| + 2|o'|)(1 + 3u)|rcp| as in the float form). o':
/// the moved origin.
/// r_out (optional): r, for the node frame (enable_fast_node_test).
CWBVH_HD CWBVH_INLINE bool fast_node_test_applies(const NodeScale& sc, const float org_moved[3], const float rcp[3],
                                                  float tmin, int* r_out = nullptr) {
    if (sc.usable == 0 || float_as_int(tmin) < 0 || !(tmin < kInfinity)) return false;
    float rmax = 0.0f, rmin = kInfinity, omax = 0.0f;
    for (int a = 0; a < 3; ++a) {
        const float ar = abs_fm(rcp[a]);
        if (!(ar >= kFloatMin && ar < kInfinity)) return false;  // also NaN
        rmax = ar > rmax ? ar : rmax;
        rmin = ar < rmin ? ar : rmin;
        const float ao = abs_fm(org_moved[a]);
        if (!(ao < kInfinity)) return false;
        omax = ao > omax ? ao : omax;
    }
    const int r = float_exponent(rmax);
    if (r_out) *r_out = r;
    if (r - float_exponent(rmin) > kFastMaxRcpSpread) return false;
    const int em = int(sc.e_max), en = int(sc.e_floor);
    if (r > 222 - em || r < -11 - en) return false;
    // Each sum and product below rounds to nearest (relative error <= u); the factor
    // 2 between 2^125 and the 2^126 the analysis needs absorbs them.
    const float reach = 65536.0f * sc.scale_max + sc.plane_max + 2.0f * omax;
    const float f_max = bits_to_float(uint32_t(243 - en - r) << 23);  // 2^(116 - e_floor - r), normal by the above
    const float slab = reach * rmax;
    return slab < kFastSlabLimit && slab * f_max < kFastSlabLimit;
}

/// Lets `r` use intersect_node_fast when fast_node_test_applies: moves the origin to
/// o' = RN(o + tmin d) for norcp (dir: the ray's direction; tmin: the lane's, already
/// +0 for a -0 tmin) and sets the node frame's ray part, frame = (243 - r) << 23. The
/// scalar test keeps using org.
CWBVH_HD CWBVH_INLINE void enable_fast_node_test(NodeRay& r, const NodeScale& sc, const float dir[3], float tmin) {
    float moved[3], norcp[3];
    for (int a = 0; a < 3; ++a) {
        moved[a] = fma_rn(tmin, dir[a], r.org[a]);
        norcp[a] = -mul_rn(moved[a], r.rcp[a]);
    }
    int rexp = 0;
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
    // Before sm_80 intersect_node_dispatch runs the reference test for every ray, which
    // reads reach: norcp must not overwrite it there.
    const bool fast = false;
    (void)sc;
#else
    const bool fast = r.zero_axis_bits() == 0 && fast_node_test_applies(sc, moved, r.rcp, tmin, &rexp);
#endif
    // Keeps the zero and open axis bits (a tmin < 0 ray never takes the fast test, and its
    // open axes must stay open).
    r.zero_axes = (r.zero_axes & ~NodeRay::kFastBit) | (fast ? NodeRay::kFastBit : 0u);
    r.frame = fast ? uint32_t(243 - rexp) << 23 : 0u;
    // norcp shares its registers with reach, which the reference test reads (NodeRay).
    if (fast)
        for (int a = 0; a < 3; ++a) r.norcp[a] = norcp[a];
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
/// intersect_node_scalar; tmin is in the moved origin and the node frame's ray part in
/// r.frame (enable_fast_node_test). frame_word: the scene's NodeScale::frame_word, from
/// somewhere the compiler cannot see through: the kernel passes its launch parameter, in
/// the constant bank, which takes no register.
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_fast(const NodeWords& n, const NodeRay& r, float tmax, uint32_t frame_word) {
    const uint32_t* lo_w = n.w + 8;
    const uint32_t* hi_w = n.w + 14;
    const uint32_t* meta_w = n.w + 6;
    const uint32_t e_w = n.w[3];
    // The node frame: f = 2^(116 - e_max - r), from r.frame = (243 - r) << 23, with the
    // node's largest exponent taken at least e_floor (NodeScale).
    const uint32_t e_a[3] = {byte_perm(e_w, 0u, 0x4440u), byte_perm(e_w, 0u, 0x4441u), byte_perm(e_w, 0u, 0x4442u)};
    const uint32_t e_node = umax3(e_a[0], e_a[1], e_a[2]);
    const uint32_t e_max = e_node > (frame_word >> 8) ? e_node : (frame_word >> 8);
    const uint32_t f_bits = r.frame - (e_max << 23);
    const float f = bits_to_float(f_bits);
    const float f20 = bits_to_float(f_bits - (20u << 23));  // 2^-20 f
    float J[3], O[3], Sf[3], t[3];
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
        // J = 2^24 2^(e_a - 127) f rcp = 2^(e_a - e_max + 13 - r) rcp: exact, or below
        // 2^-126 (an axis far flatter than the node's widest: then within 2^-150 of it,
        // or 0, which the floor of E covers). f rcp first: it lies in [2^(116 - e_max),
        // 2^(117 - e_max)), a normal float, while 2^(e_a - 103) f can overflow (a huge
        // scene, |dir| beyond 2^114).
        const float scale24 = bits_to_float((e_a[a] + 24u) << 23);  // 2^(e_a - 103)
        J[a] = mul_rn(scale24, mul_rn(f, r.rcp[a]));
        O[a] = fma_rn(bits_to_float(n.w[a]), r.rcp[a], r.norcp[a]);  // RN(p rcp - RN(o' rcp))
        // The float part's error bound in the node frame, with the subnormal-half floor.
        Sf[a] = fma_rn(add_rn(abs_fm(O[a]), abs_fm(r.norcp[a])), f20, 1.1920928955078125e-07f);  // + 2^-23
        const float G = fma_rn(abs_fm(J[a]), 1.52587890625e-05f, Sf[a]);  // + the grid's extent, 2^-16 J
        t[a] = fma_rd(O[a], f, -G);
    }
    const float C = bits_to_float(uint32_t(imax3_relu(float_as_int(t[0]), float_as_int(t[1]), float_as_int(t[2]))));
    uint32_t on[3], of[3];
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
        const float D = fma_rn(O[a], f, -C);
        const float Z = fma_rn(abs_fm(J[a]), 1.6763806343078613e-08f, Sf[a]);  // 1.125 * 2^-26 J
        const float E = fma_rn(abs_fm(D), 5.18798828125e-04f, Z);              // 1.0625 * 2^-11 |D|
        on[a] = h2_broadcast_rd(sub_rd(D, E));  // near planes' offset, rounded down twice
        of[a] = h2_broadcast_ru(add_ru(D, E));  // far planes', up
    }
    const uint32_t jxy = h2_pack(J[0], J[1]);
    const uint32_t jz = h2_pack(J[2], J[2]);
    const uint32_t j2[3] = {h2_lo(jxy), h2_hi(jxy), jz};
    const uint32_t tmax_h = h2_broadcast_ru(fma_ru(tmax, f, -C));
    uint32_t near_w[6], far_w[6];
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
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
    for (int pr = 0; pr < kWidth / 2; ++pr) {
        const int h = pr >> 1;
        // Slots 2pr and 2pr + 1: plane bytes b and b + 1 of the word, each under a zero
        // byte (frame_word's low byte): the halves q 2^-24.
        const uint32_t sel = (pr & 1) ? 0x4342u : 0x4140u;
        uint32_t tn[3], tf[3];
        CWBVH_UNROLL
        for (int a = 0; a < 3; ++a) {
            tn[a] = h2_fma(byte_perm(near_w[2 * a + h], frame_word, sel), j2[a], on[a]);
            tf[a] = h2_fma(byte_perm(far_w[2 * a + h], frame_word, sel), j2[a], of[a]);
        }
        const uint32_t tnear = vimax3_s16x2_relu(tn[0], tn[1], tn[2]);
        const uint32_t tfar = h2_min(vimin3_s16x2(tf[0], tf[1], tf[2]), tmax_h);
        bool hit[2];
        h2_le(tnear, tfar, hit[0], hit[1]);
        CWBVH_UNROLL
        for (int k = 0; k < 2; ++k) {
            const int s = 2 * pr + k;
            if (hit[k]) {
                // Empty slots have meta 0: no bits.
                const uint32_t bits = byte_perm(bits_w[h], 0u, 0x4440u | uint32_t(s & 3));
                hitmask |= shl_wrap(bits, index_w[h] >> (8 * (s & 3)));
            }
        }
    }
    return hitmask;
}

/// The fast test on a node in its struct form (the host: tests, the CPU traversal).
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_fast(const CwbvhNode& n, const NodeRay& r, float tmax, uint32_t frame_word) {
    return intersect_node_fast(node_words(n), r, tmax, frame_word);
}

/// The node test a traversal runs on `r`: intersect_node_fast where the ray's set-up
/// enabled it (r.uses_fast_test()) on sm_80 and later, the reference arithmetic otherwise.
/// sm_90 has the three-input integer min/max in one instruction (DPX); sm_80-89 (A100,
/// Ampere, Ada) emulate them with two-input ones and still gain: node step 289 against 377
/// by bench/gpu/step_sizes.sh sm_80, 80 registers and no spills. On sm_75 the kernels would
/// spill: reference arithmetic. On the host the flag selects too (the warp model and the
/// tests run what the kernel runs).
/// frame_word: NodeScale::frame_word (see there). The kernels pass NodeWords (see there),
/// the host CPU traversal the node in place.
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_dispatch(const NodeWords& n, const NodeRay& r, float tmin, float tmax,
                                                       uint32_t frame_word) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
    (void)frame_word;
    return intersect_node(node_from_words(n), r, tmin, tmax);
#else
    if (r.uses_fast_test()) return intersect_node_fast(n, r, tmax, frame_word);
    return intersect_node(node_from_words(n), r, tmin, tmax);
#endif
}
CWBVH_HD CWBVH_INLINE uint32_t intersect_node_dispatch(const CwbvhNode& n, const NodeRay& r, float tmin, float tmax,
                                                       uint32_t frame_word) {
#if defined(__CUDA_ARCH__) && __CUDA_ARCH__ < 800
    (void)frame_word;
    return intersect_node(n, r, tmin, tmax);
#else
    return r.uses_fast_test() ? intersect_node_fast(n, r, tmax, frame_word) : intersect_node(n, r, tmin, tmax);
#endif
}


/// The scene constants for `count` nodes (host, once per upload: O(nodes)). Exponents
/// outside 1..kFastMaxExponent (0 decodes every plane to p, whose planes the node frame
/// cannot step) make the scene use intersect_node_scalar throughout.
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
    NodeScale sc{0.0f, 0.0f, 0u, 0u, 0u, 0u};
    if (count == 0 || !finite || emin < 1 || emax > kFastMaxExponent) return sc;
    // Round up to float: the set-up test must not underestimate.
    float pf = float(plane);
    if (double(pf) < plane) pf = bits_to_float(float_to_bits(pf) + 1u);
    sc.plane_max = pf;
    sc.scale_max = exponent_scale(uint8_t(emax));
    sc.e_max = emax;
    sc.e_floor = emax > 101 ? emax - 100 : 1u;
    sc.frame_word = sc.e_floor << 8;
    sc.usable = 1u;
    return sc;
}

/// Constants that hold for the nodes of both a and b (a two-level scene: NODE and
/// TLAS): the larger bounds, the wider exponent range; usable only when both are.
inline NodeScale merge_node_scale(const NodeScale& a, const NodeScale& b) {
    if (a.usable == 0 || b.usable == 0) return NodeScale{};
    NodeScale m = a;
    m.plane_max = a.plane_max > b.plane_max ? a.plane_max : b.plane_max;
    m.scale_max = a.scale_max > b.scale_max ? a.scale_max : b.scale_max;
    m.e_max = a.e_max > b.e_max ? a.e_max : b.e_max;
    m.e_floor = m.e_max > 101 ? m.e_max - 100 : 1u;
    m.frame_word = m.e_floor << 8;
    return m;
}

}  // namespace cwbvh
