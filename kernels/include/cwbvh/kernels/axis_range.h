// How far a ray segment reaches along one axis: the culling of the node tests on an axis
// where their slab arithmetic gives up.
//
// Both node tests (node_intersect.h for CWBVH, traverse_bvh2.h for BVH2) compute slab
// distances t = (plane - o) * RN(1/d) in float. On an axis with d = +-0, a subnormal d
// (RN(1/d) overflows), |d| > 2^126 (RN(1/d) is subnormal), or slab terms beyond 2^126
// (CWBVH: huge coordinates), that arithmetic is unbounded, and the tests used to accept
// every box on that axis. A ray differing from an axis-parallel one by a subnormal
// component then visited every node (bunny: 5,515 nodes and 56,737 triangle tests per
// ray; tests/traverse/traverse_test.cpp, TinyAndHugeDirectionComponentsStillCull).
//
// What culls there instead: a hit beyond the float range is no hit (spec/rays.md: t
// rounds to a finite float, so exact t < 2^128), so only t in [tmin, min(tmax, 2^128)]
// matters. For tmin >= 0 coordinate a then stays between o and the reach
// e = o + d min(tmax, 2^128), and a box whose [lo, hi] on that
// axis misses [min(o, e), max(o, e)] cannot be hit. For d = +-0, e = o: the exact
// "origin inside the slab" test. For a subnormal d the range is at most 2^-126 * 2^128 = 4
// long (1e-40: 0.034); for |d| > 2^126 it is everything ahead of the origin, so such a ray
// still loses the culling of what lies behind. With tmin < 0 the range extends behind
// the origin as well: such an axis (d != 0) is left open, no culling, as before.
//
// The reach is computed once per ray (set-up), from the ray's tmax, which only shrinks:
// float compares in the node step, nothing wider. Rounding: d * T is exact in double
// (24 x 24 significand bits, exponents 2^-298 .. 2^256; T = 2^128 is a power of two), o + d T rounds once (within
// 2^-53 |x| of the exact x; x = 0 only when the exact sum is 0), the end moves outwards by
// 2^-50 |x| and that sum rounds once more (net outward by more than 2^-53 |x|), then the
// conversion to float rounds outwards (float_round_up / float_round_down,
// cwbvh/format/float_round.h: one directed conversion on the device).
// For 2^-64 <= |d| <= 2^64 no float scene is out of the slab's range because of d
// (an axis goes unbounded there only for coordinates beyond 2^120): the reach is then
// taken as +-inf, one select instead of the double arithmetic.
#pragma once

#include <cstdint>

#include "cwbvh/format/float_round.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/fp.h"

namespace cwbvh {

inline constexpr float kFloatMax = 3.40282347e+38f;  ///< FLT_MAX
/// 2^128: the least t that rounds to +inf in float. The triangle tests report a hit whose
/// exact t is below it (RN(t) = FLT_MAX), so the reach must extend that far.
inline constexpr double kTwo128 = 3.4028236692093846e+38;

/// Whether segment_reach takes its double path for direction component d (d != 0 outside
/// 2^-64 .. 2^64); otherwise the reach is o (d = +-0) or +-inf.
CWBVH_HD CWBVH_INLINE bool reach_needs_double(float d) {
    const float ad = abs_f(d);
    return d != 0.0f && !(ad >= 5.42101086e-20f && ad <= 1.84467441e+19f);  // 2^-64 .. 2^64
}

/// The reach of the segment on one axis (see above): a float e such that for t in
/// [max(tmin, 0), min(tmax, 2^128)] coordinate o + d t lies between o and e. tmax: not
/// NaN, >= 0 when it matters (a traceable ray with tmin >= 0).
CWBVH_HD CWBVH_INLINE float segment_reach(float o, float d, float tmax) {
    if (d == 0.0f) return o;
    if (!reach_needs_double(d)) return d > 0.0f ? kInfinity : -kInfinity;
    const double t = tmax > kFloatMax ? kTwo128 : double(tmax);
    const double x = double(o) + double(d) * t;  // d * t exact: one rounding, fma or not
    constexpr double kWiden = 8.8817841970012523e-16;  // 2^-50
    const bool up = d > 0.0f;  // the reach lies above o: round up, else down
    const double w = up ? x + abs_d(x) * kWiden : x - abs_d(x) * kWiden;
    return up ? float_round_up(w) : float_round_down(w);  // outwards
}

/// segment_reach for the three axes of a ray. The double path, rare, runs in one rolled
/// loop (one copy in device code instead of three).
CWBVH_HD CWBVH_INLINE void segment_reaches(const float org[3], const float dir[3], float tmax, float reach[3]) {
    uint32_t wide = 0;
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
        reach[a] = dir[a] == 0.0f ? org[a] : dir[a] > 0.0f ? kInfinity : -kInfinity;
        wide |= reach_needs_double(dir[a]) ? 1u << a : 0u;
    }
    if (wide == 0) return;
    CWBVH_NO_UNROLL
    for (int a = 0; a < 3; ++a) {
        if (((wide >> a) & 1u) == 0) continue;
        const bool x = a == 0, y = a == 1;
        const float e = segment_reach(x ? org[0] : y ? org[1] : org[2], x ? dir[0] : y ? dir[1] : dir[2], tmax);
        reach[0] = x ? e : reach[0];
        reach[1] = y ? e : reach[1];
        reach[2] = a == 2 ? e : reach[2];
    }
}

/// Whether the box planes [lo, hi] on an axis meet the range between o and its reach e.
CWBVH_HD CWBVH_INLINE bool reach_meets(float o, float e, float lo, float hi) {
    return lo <= max_f(o, e) && min_f(o, e) <= hi;
}

}  // namespace cwbvh
