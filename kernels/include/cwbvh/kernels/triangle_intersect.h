// Ray-triangle tests, chosen at compile time by TriangleTest.
//   kWatertight: Woop, Benthin, Wald 2013, "Watertight Ray/Triangle Intersection"
//                (JCGT 2(1)), with the paper's double-precision fallback.
//   kFast:       Moller, Trumbore 1997, with no absolute epsilon; not watertight. Its
//                float determinant is a product of two edges and the direction
//                (~L^2 |d|): where that under- or overflows, the triangle is missed
//                (with |d| ~ L: L outside about 2^-40 .. 2^40; spec/rays.md).
// Both accept hits with tmin <= t <= tmax (closed), t finite, and report u, v as the
// barycentric weights of v1 and v2. A triangle whose plane contains the ray is a miss
// in both (watertight: plane_t certifies the sign of n.d; fast: det == 0).
#pragma once

#include <cmath>
#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/fp.h"
#include "cwbvh/kernels/ray.h"

namespace cwbvh {

enum class TriangleTest : uint32_t { kWatertight = 0, kFast = 1 };

struct TriangleHit {
    float t, u, v;
};

// ---------------------------------------------------------------------------
// Watertight test (Woop et al. 2013)
// ---------------------------------------------------------------------------

/// Per-ray shear constants (paper, section 3): kz = dominant axis of dir, kx, ky the
/// other two, swapped when dir[kz] < 0 to keep the winding; the shear maps dir to
/// (0, 0, dir[kz]): sheared x = A[kx] - sx A[kz], y = A[ky] - sy A[kz] for A = v - o,
/// sx = dir[kx] / dir[kz], sy = dir[ky] / dir[kz].
///
/// Written as two rows, x = A.mx and y = A.my with mx = e_kx - sx e_kz and
/// my = e_ky - sy e_kz (each an exact 1, an exact 0 and one quotient), so a triangle
/// test reads its vertices in their stored axis order: picking v[kx], v[ky], v[kz] from
/// registers took two selects per coordinate, 18 per triangle, plus decoding kx, ky, kz
/// (issue 18). Every quantity of the test is a function of the vertex and the ray alone
/// (the rounding of A.mx depends on which axis holds the 0, a per-ray fact), which is
/// all the watertightness argument below needs. org is the ray's origin as given (the
/// lane's NodeRay holds the same values: no extra registers on the GPU).
struct WatertightRay {
    float org[3];  ///< the ray's origin
    float dir[3];  ///< the ray's direction (plane_t and the range stage; unpermuted)
    float mx[3];   ///< sheared x = (v - org) . mx
    float my[3];   ///< sheared y = (v - org) . my
};

CWBVH_HD CWBVH_INLINE WatertightRay make_watertight_ray(const Ray& r) {
    WatertightRay w;
    const float ax = abs_f(r.dir[0]), ay = abs_f(r.dir[1]), az = abs_f(r.dir[2]);
    const int kz = (ax > ay) ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    // Constant indices only below (selects): an array written at a run-time index would
    // live in local memory on the GPU.
    const float dz = kz == 0 ? r.dir[0] : (kz == 1 ? r.dir[1] : r.dir[2]);
    if (dz < 0.0f) {
        const int tmp = kx;
        kx = ky;
        ky = tmp;
    }
    const float dx = kx == 0 ? r.dir[0] : (kx == 1 ? r.dir[1] : r.dir[2]);
    const float dy = ky == 0 ? r.dir[0] : (ky == 1 ? r.dir[1] : r.dir[2]);
    // dir[kz] != 0 for a traceable ray. These roundings are shared by every triangle
    // the ray meets, so they cannot open a crack between neighbours.
    const float sx = -(dx / dz), sy = -(dy / dz);
    CWBVH_UNROLL
    for (int a = 0; a < 3; ++a) {
        w.org[a] = r.org[a];
        w.dir[a] = r.dir[a];
        w.mx[a] = a == kx ? 1.0f : (a == kz ? sx : 0.0f);
        w.my[a] = a == ky ? 1.0f : (a == kz ? sy : 0.0f);
    }
    return w;
}

/// (v - org) . m as the tests compute it: the product of axis 2, then two fmas (6
/// instructions per vertex on the GPU where three products and two sums took 10: 12 per
/// triangle, issue 18). One of the three terms is an exact 0 (v - org finite: its fma
/// adds 0 and changes at most the sign of an exact zero) and one an exact copy of
/// v - org, so the result is RN(A[kx] + RN(-sx A[kz])) when kz comes before kx in the
/// order 2, 1, 0, and RN(A[kx] - sx A[kz]) (one rounding) when it comes after: both
/// depend only on the vertex and the ray, which is all watertightness needs, and
/// bench/results/cpu/2026-11-26-shear-rows measured this form (0 errors). The host
/// needs a real fma for the same bits: the CPU traversal is compiled twice, for FMA
/// hardware and without (kernels/src/cpu_trace.cpp: target_clones), so that only CPUs
/// without FMA pay libm's fmaf.
CWBVH_HD CWBVH_INLINE float shear_row(const float a[3], const float m[3]) {
    return fma_rn(a[0], m[0], fma_rn(a[1], m[1], mul_rn(a[2], m[2])));
}

/// Hit distance: t = n.(v0 - o) / n.d, n = (v1 - v0) x (v2 - v0), in double from the
/// float inputs (axes in their stored order). Not the
/// paper's T / det: its float sheared z and edge functions (cancelling near an edge)
/// err by ~u |v - o|, so its t was off by ~u |v - o| / cos, far more than ulps of t
/// (0.3-0.7 % for a sponza bounce ray 0.027 from its hit, 7 from the far vertices);
/// the box tests bound the exact t with 2^-21 slack, so a larger error let a visit
/// order cull the subtree of the closest hit (BVH2 != CWBVH). Here float differences
/// are exact in double (or rounded once), products and sums round to nearest at
/// 2^-53, so the relative error is ~2^-52 x the cancellation |v - o| / (t cos)
/// (~2^11 on that ray): float(t) is within 1 ulp of the exact t up to ~2^28.
/// Nearest rounding everywhere (mul_rn/add_rn/sub_rn: never contracted; IEEE '/'),
/// so host and device agree bitwise.
///
/// False when the ray may lie in the plane: the sign of n.d must be certain. Each
/// computed n component errs from the exact cross product of the exact edges by at most
/// 4u (P = |first product| + |second product|, u = 2^-53: the edges' roundings, the two
/// products', the difference's), and the dot product adds 3u |n_i d_i| terms, so
/// |den - DEN| <= ~7u sum P_i |d_i| (no under- or overflow: floats' differences, their
/// products and the n_i d_i terms lie in [2^-447, 2^387], far inside double's range). With 2^-49 = 16u in place of 7u, |den| > B proves
/// DEN != 0 with its sign. A ray in the plane (DEN = 0 exactly) then never passes: its
/// float edge functions are rounding noise, and so was n.d; t = noise / noise was reported
/// as a hit (spec/rays.md: such a ray is not hit; tests/traverse/triangle_edge_cases_test).
/// The cost is rays within ~2^-49 (relative to the edges' products) of the plane's
/// direction: they miss, where t would have been meaningless anyway.
CWBVH_HD CWBVH_INLINE bool plane_t(const WatertightRay& w, const float* v0, const float* v1, const float* v2,
                                   double& t) {
    const double px = v0[0], py = v0[1], pz = v0[2];
    const double e1x = sub_rn(double(v1[0]), px), e1y = sub_rn(double(v1[1]), py);
    const double e1z = sub_rn(double(v1[2]), pz);
    const double e2x = sub_rn(double(v2[0]), px), e2y = sub_rn(double(v2[1]), py);
    const double e2z = sub_rn(double(v2[2]), pz);
    const double ax = mul_rn(e1y, e2z), bx = mul_rn(e1z, e2y);
    const double ay = mul_rn(e1z, e2x), by = mul_rn(e1x, e2z);
    const double az = mul_rn(e1x, e2y), bz = mul_rn(e1y, e2x);
    const double nx = sub_rn(ax, bx), ny = sub_rn(ay, by), nz = sub_rn(az, bz);
    const double dx = w.dir[0], dy = w.dir[1], dz = w.dir[2];
    const double num = add_rn(add_rn(mul_rn(nx, sub_rn(px, double(w.org[0]))), mul_rn(ny, sub_rn(py, double(w.org[1])))),
                              mul_rn(nz, sub_rn(pz, double(w.org[2]))));
    const double den = add_rn(add_rn(mul_rn(nx, dx), mul_rn(ny, dy)), mul_rn(nz, dz));
    const double bound =
        mul_rn(add_rn(add_rn(mul_rn(add_rn(fabs(ax), fabs(bx)), fabs(dx)), mul_rn(add_rn(fabs(ay), fabs(by)), fabs(dy))),
                      mul_rn(add_rn(fabs(az), fabs(bz)), fabs(dz))),
               1.7763568394002505e-15);  // 2^-49
    if (!(fabs(den) > bound)) return false;  // the plane may contain the ray (or NaN)
    t = num / den;
    return t == t;
}

/// Watertight test. Watertightness argument: the sheared vertex coordinates depend
/// only on the vertex and the ray, and an edge function of a shared edge is computed
/// as fl(fl(a*b) - fl(c*d)) in one triangle and exactly its negation in the other
/// (mul_rn/sub_rn: never contracted to an fma, which would break the symmetry).
/// Round-to-nearest is monotone, so a nonzero float edge function has the sign of the
/// exact one; a zero one is recomputed in double, where the products of two floats are
/// exact and one rounding keeps the sign. So every edge sign is exact for the sheared
/// vertices, and a ray through an edge or vertex hits at least one of the triangles
/// sharing it.
/// The watertight test's first stage, which decides most misses: the vertices
/// relative to the origin, sheared, and the three edge functions in float. Returns
/// false when the edge signs are mixed (exact: a miss); otherwise the caller goes on
/// with the hit distance. (Split out so that bench/gpu/step_probe.cu can size it.)
struct WatertightEdges {
    float ax, ay, bx, by, cx, cy;  ///< sheared x, y of the vertices
    float eu, ev, ew;              ///< edge functions (scaled barycentrics)
};
CWBVH_HD CWBVH_INLINE bool watertight_edges(const WatertightRay& w, const float* v0, const float* v1,
                                            const float* v2, WatertightEdges& e) {
    // Vertices relative to the origin, then sheared (WatertightRay: two rows).
    const float a[3] = {sub_rn(v0[0], w.org[0]), sub_rn(v0[1], w.org[1]), sub_rn(v0[2], w.org[2])};
    const float b[3] = {sub_rn(v1[0], w.org[0]), sub_rn(v1[1], w.org[1]), sub_rn(v1[2], w.org[2])};
    const float c[3] = {sub_rn(v2[0], w.org[0]), sub_rn(v2[1], w.org[1]), sub_rn(v2[2], w.org[2])};
    e.ax = shear_row(a, w.mx);
    e.ay = shear_row(a, w.my);
    e.bx = shear_row(b, w.mx);
    e.by = shear_row(b, w.my);
    e.cx = shear_row(c, w.mx);
    e.cy = shear_row(c, w.my);

    // Scaled barycentrics (edge functions).
    e.eu = sub_rn(mul_rn(e.cx, e.by), mul_rn(e.cy, e.bx));
    e.ev = sub_rn(mul_rn(e.ax, e.cy), mul_rn(e.ay, e.cx));
    e.ew = sub_rn(mul_rn(e.bx, e.ay), mul_rn(e.by, e.ax));
    // Exact-sign early out: mixed signs iff the smallest is < 0 and the largest > 0.
    // fminf/fmaxf (host and device alike, IEEE minNum/maxNum) return the other operand
    // for a NaN, so a NaN edge function (inf - inf) counts as neither sign; all three
    // NaN fail both comparisons: the test goes on. Four min/max and two compares
    // instead of a branchy or-chain.
    const float lo = fminf(fminf(e.eu, e.ev), e.ew), hi = fmaxf(fmaxf(e.eu, e.ev), e.ew);
    return !(lo < 0.0f && hi > 0.0f);
}

/// The watertight test's second stage, in float: true when the hit distance T of the
/// triangle's plane lies certainly outside [tmin, tmax] (a miss, decided without
/// double precision); false when float cannot decide (the caller then runs plane_t in
/// double, as before). Most triangles whose edge signs agree lie behind the closest hit
/// found so far, and this stage rejects them in about 50 float instructions instead of
/// the double path's 200 (issue 18).
///
/// Exact quantities (axes in their stored order; o, d the ray): E1 = v1 - v0, E2 = v2 - v0,
/// N = E1 x E2, A = v0 - o, NUM = N.A, DEN = N.d, T = NUM / DEN (plane_t computes the
/// same T). The float values below carry these bounds (u = 2^-24, every operation
/// rounded to nearest, fma_rn rounding once; first order, the second-order terms are
/// below u^2 of the same sums):
///   e1, e2, a: relative error <= u each (a difference that is subnormal is exact);
///   n_i = fma(e1_j, e2_k, -RN(e1_k e2_j)): |n_i - N_i| <= 4u P_i + 2^-149,
///     P_i = |e1_j e2_k| + |e1_k e2_j| (computed as fma(|e1_j|, |e2_k|, |RN(e1_k e2_j)|));
///   num = fma-dot(n, a): |num - NUM| <= (3u + 4u + u) sum P_i |a_i| + 2^-149 (sum |a_i| + 2);
///   den = fma-dot(n, d) (d exact): |den - DEN| <= 7u sum P_i |d_i| + 2^-149 (sum |d_i| + 2);
/// where the 2^-149 terms cover products and sums that land in the subnormal range
/// (absolute error <= 2^-150 each). Slack: en = 2^-20 M_num + 2^-146 (sum |a_i| + 1)
/// and ed = 2^-20 M_den + 2^-146 (sum |d_i| + 1), M = the computed sums of P_i |.|:
/// 16u instead of 8u leaves 8u of the sums for the roundings of the comparisons below
/// (at most 4u of each side; |den| <= M_den (1 + 8u)), and the absolute terms are
/// 4-8 times what the subnormal range needs.
/// With den' = |den| > ed the sign of DEN is den's; num' = num with den's sign flipped in:
///   far:  tmax >= 0 and RN(num' - en) > RN(tmax RN(den' + ed))  =>  T > tmax;
///   near: tmin >= 0 and RN(num' + en) < RN(tmin RN(den' - ed))  =>  T < tmin
///         (num' + en < 0 means NUM < 0: T < 0 <= tmin).
/// Overflow: with P_x + P_y + P_z < 2^126 every |n_i| is finite; a num or den that
/// overflows has an infinite M, so en or ed is infinite and every comparison above is
/// false (inf - inf is NaN); NaN anywhere makes them false too. A triangle this stage
/// rejects is one plane_t would reject: its double t is within 2^-40 of T relative,
/// far inside the 16u margin.
CWBVH_HD CWBVH_INLINE bool watertight_range_miss(const WatertightRay& w, const float* v0, const float* v1,
                                                 const float* v2, float tmin, float tmax) {
    const float px0 = v0[0], py0 = v0[1], pz0 = v0[2];
    const float e1x = sub_rn(v1[0], px0), e1y = sub_rn(v1[1], py0), e1z = sub_rn(v1[2], pz0);
    const float e2x = sub_rn(v2[0], px0), e2y = sub_rn(v2[1], py0), e2z = sub_rn(v2[2], pz0);
    const float ax = sub_rn(px0, w.org[0]), ay = sub_rn(py0, w.org[1]), az = sub_rn(pz0, w.org[2]);
    const float mx = mul_rn(e1z, e2y), my = mul_rn(e1x, e2z), mz = mul_rn(e1y, e2x);
    const float nx = fma_rn(e1y, e2z, -mx), ny = fma_rn(e1z, e2x, -my), nz = fma_rn(e1x, e2y, -mz);
    const float Px = fma_rn(abs_fm(e1y), abs_fm(e2z), abs_fm(mx));
    const float Py = fma_rn(abs_fm(e1z), abs_fm(e2x), abs_fm(my));
    const float Pz = fma_rn(abs_fm(e1x), abs_fm(e2y), abs_fm(mz));
    if (!(add_rn(add_rn(Px, Py), Pz) < 8.5070591730234616e+37f)) return false;  // 2^126; NaN
    const float dx = w.dir[0], dy = w.dir[1], dz = w.dir[2];
    const float num = fma_rn(nx, ax, fma_rn(ny, ay, mul_rn(nz, az)));
    const float den = fma_rn(nx, dx, fma_rn(ny, dy, mul_rn(nz, dz)));
    const float Mn = fma_rn(Px, abs_fm(ax), fma_rn(Py, abs_fm(ay), mul_rn(Pz, abs_fm(az))));
    const float Md = fma_rn(Px, abs_fm(dx), fma_rn(Py, abs_fm(dy), mul_rn(Pz, abs_fm(dz))));
    const float sa = add_rn(add_rn(abs_fm(ax), abs_fm(ay)), abs_fm(az));
    const float sd = add_rn(add_rn(abs_fm(dx), abs_fm(dy)), abs_fm(dz));
    const float en = fma_rn(Mn, 9.5367431640625e-07f, fma_rn(sa, 1.1210387714598537e-44f, 1.1210387714598537e-44f));
    const float ed = fma_rn(Md, 9.5367431640625e-07f, fma_rn(sd, 1.4947183447801235e-44f, 1.1210387714598537e-44f));
    const float dp = abs_fm(den);
    const float np = bits_to_float(float_to_bits(num) ^ (float_to_bits(den) & 0x80000000u));
    if (!(dp > ed)) return false;  // the sign of DEN is not certain (or NaN)
    const bool far = tmax >= 0.0f && sub_rn(np, en) > mul_rn(tmax, add_rn(dp, ed));
    const bool near = tmin >= 0.0f && add_rn(np, en) < mul_rn(tmin, sub_rn(dp, ed));
    return far || near;
}

/// watertight_range_miss's float quantities, for watertight_range_interval: T = NUM / DEN
/// with the signs folded so that T = np' / dp' for the exact np', dp' > 0, and
/// |np - np'| <= en - 8u M_num, |dp - dp'| <= ed - 8u M_den (the bounds above, with the
/// spare 8u of each sum left over). False when float cannot certify the sign of DEN (or P
/// overflows, or NaN). The same operations as watertight_range_miss, statement for
/// statement (tests/traverse/triangle_range_test.cpp: the two decide the same misses).
/// Not shared with it on purpose: watertight_range_miss written over this function
/// compiled to a BVH2 kernel of 72 registers instead of 64, and CWBVH kernels with
/// spills (nvcc 13.0, sm_90), with the same operations.
CWBVH_HD CWBVH_INLINE bool watertight_plane_float(const WatertightRay& w, const float* v0, const float* v1,
                                                  const float* v2, float& np, float& dp, float& en, float& ed) {
    const float px0 = v0[0], py0 = v0[1], pz0 = v0[2];
    const float e1x = sub_rn(v1[0], px0), e1y = sub_rn(v1[1], py0), e1z = sub_rn(v1[2], pz0);
    const float e2x = sub_rn(v2[0], px0), e2y = sub_rn(v2[1], py0), e2z = sub_rn(v2[2], pz0);
    const float ax = sub_rn(px0, w.org[0]), ay = sub_rn(py0, w.org[1]), az = sub_rn(pz0, w.org[2]);
    const float mx = mul_rn(e1z, e2y), my = mul_rn(e1x, e2z), mz = mul_rn(e1y, e2x);
    const float nx = fma_rn(e1y, e2z, -mx), ny = fma_rn(e1z, e2x, -my), nz = fma_rn(e1x, e2y, -mz);
    const float Px = fma_rn(abs_fm(e1y), abs_fm(e2z), abs_fm(mx));
    const float Py = fma_rn(abs_fm(e1z), abs_fm(e2x), abs_fm(my));
    const float Pz = fma_rn(abs_fm(e1x), abs_fm(e2y), abs_fm(mz));
    if (!(add_rn(add_rn(Px, Py), Pz) < 8.5070591730234616e+37f)) return false;  // 2^126; NaN
    const float dx = w.dir[0], dy = w.dir[1], dz = w.dir[2];
    const float num = fma_rn(nx, ax, fma_rn(ny, ay, mul_rn(nz, az)));
    const float den = fma_rn(nx, dx, fma_rn(ny, dy, mul_rn(nz, dz)));
    const float Mn = fma_rn(Px, abs_fm(ax), fma_rn(Py, abs_fm(ay), mul_rn(Pz, abs_fm(az))));
    const float Md = fma_rn(Px, abs_fm(dx), fma_rn(Py, abs_fm(dy), mul_rn(Pz, abs_fm(dz))));
    const float sa = add_rn(add_rn(abs_fm(ax), abs_fm(ay)), abs_fm(az));
    const float sd = add_rn(add_rn(abs_fm(dx), abs_fm(dy)), abs_fm(dz));
    en = fma_rn(Mn, 9.5367431640625e-07f, fma_rn(sa, 1.1210387714598537e-44f, 1.1210387714598537e-44f));
    ed = fma_rn(Md, 9.5367431640625e-07f, fma_rn(sd, 1.4947183447801235e-44f, 1.1210387714598537e-44f));
    dp = abs_fm(den);
    np = bits_to_float(float_to_bits(num) ^ (float_to_bits(den) & 0x80000000u));
    if (!(dp > ed)) return false;  // the sign of DEN is not certain (or NaN)
    return true;
}

/// What the float stage can say about a triangle whose edge signs agree (GPU lanes that
/// defer the double-precision hit distance: cwbvh_lane.h, test_triangle_deferred).
enum class RangeVerdict : uint32_t {
    kMiss = 0,       ///< T certainly outside [tmin, tmax]: watertight_range_miss
    kInside = 1,     ///< [lo, hi] holds the float t the whole test reports, tmin <= lo, hi <= tlo
    kUndecided = 2,  ///< neither: only the whole test can tell
};

/// The float range stage with bounds (issue 18). kMiss exactly when watertight_range_miss
/// is true. kInside when float certifies all of the following, so that the whole test
/// (intersect_triangle_watertight) on the same inputs, with any tmax' >= hi, passes its
/// plane and range tests and reports a t in [lo, hi]:
///   - the sign of DEN (dp > ed), so plane_t's double bound test passes: |DEN| > ed - (ed -
///     8u M_den) >= 8u_f M_den, far above plane_t's 2^-49 M_den plus its own 7u_d M_den error;
///   - lo <= dt <= hi for plane_t's double quotient dt, hence lo <= float(dt) <= hi (both are
///     floats; rounding is monotone): A_lo = nextDown(RN(np - en)) > 0 and
///     B_hi = nextUp(RN(dp + ed)) bound np' - 8u M_num and dp' + 8u M_den from below and
///     above (the float errors are within en, ed less the spare 8u of the sums), and the
///     double errors of plane_t's num and den are below 8u_d M_num and 7u_d M_den, far
///     inside the spare: A_lo / B_hi <= num_d / den_d. The double division rounds by
///     u_d = 2^-53 relative; lo = nextDown(RN(A_lo / B_hi)) lies at least 2^-25 relative
///     below A_lo / B_hi when it is a normal float (lo >= 2^-100 is required). hi mirrors
///     it with A_hi = nextUp(RN(np + en)), B_lo = nextDown(RN(dp - ed)), and must be finite;
///   - tmin <= lo and hi <= tlo.
/// The nextUp/nextDown of positive floats are their bits plus or minus one (RN(x) errs by at
/// most half a step, so one step outward bounds x); a zero or infinite operand turns into NaN
/// or a bound that fails the tests: kUndecided. Every operation is an IEEE operation rounded
/// to nearest (host and device give the same bits). tests/traverse/triangle_range_test.cpp
/// checks lo <= t <= hi against the whole test.
CWBVH_HD CWBVH_INLINE RangeVerdict watertight_range_interval(const WatertightRay& w, const float* v0,
                                                            const float* v1, const float* v2, float tmin,
                                                            float tlo, float tmax, float& lo, float& hi) {
    float np, dp, en, ed;
    if (!watertight_plane_float(w, v0, v1, v2, np, dp, en, ed)) return RangeVerdict::kUndecided;
    const float a = sub_rn(np, en);  // RN(np - en)
    const float bh = add_rn(dp, ed);
    const float ah = add_rn(np, en);
    const float bl = sub_rn(dp, ed);
    if (tmax >= 0.0f && a > mul_rn(tmax, bh)) return RangeVerdict::kMiss;   // far
    if (tmin >= 0.0f && ah < mul_rn(tmin, bl)) return RangeVerdict::kMiss;  // near
    if (!(a > 0.0f)) return RangeVerdict::kUndecided;  // T may be <= 0 (or NaN)
    // bl >= 2^-149 here: dp > ed, and a difference of floats is a multiple of 2^-149.
    const float a_lo = bits_to_float(float_to_bits(a) - 1u), b_hi = bits_to_float(float_to_bits(bh) + 1u);
    const float a_hi = bits_to_float(float_to_bits(ah) + 1u), b_lo = bits_to_float(float_to_bits(bl) - 1u);
    lo = bits_to_float(float_to_bits(a_lo / b_hi) - 1u);
    hi = bits_to_float(float_to_bits(a_hi / b_lo) + 1u);
    const bool inside = lo >= tmin && lo >= 7.8886090522101181e-31f /* 2^-100 */ && hi <= tlo &&
                        hi <= 3.4028234663852886e38f;
    return inside ? RangeVerdict::kInside : RangeVerdict::kUndecided;
}

CWBVH_HD CWBVH_INLINE bool intersect_triangle_watertight(const WatertightRay& w, const float* v0,
                                                         const float* v1, const float* v2,
                                                         float tmin, float tmax, TriangleHit& out) {
    WatertightEdges e;
    if (!watertight_edges(w, v0, v1, v2, e)) return false;
    // The float range stage runs on the GPU only. It rejects only what plane_t's double
    // range test below rejects (its bound; tests/traverse/triangle_range_test.cpp checks
    // both on the same inputs), so skipping it changes no result. On the host double is
    // as fast as float, and the stage's error terms are subnormal constants (2^-146,
    // 2^-149), which x86 handles in microcode: with the stage the CPU traversal was
    // 1.7x slower with libm fmas (2026-11-26) and still 1.7-2.2x slower with the FMA
    // clones of cpu_trace.cpp (2026-11-27, sponza_dabrovic nave and oa_oacmpctf3
    // bridges, 256x256, 1 thread; bench/results/cpu/2026-11-27-fma-shear).
#if defined(__CUDA_ARCH__)
    if (watertight_range_miss(w, v0, v1, v2, tmin, tmax)) return false;
#endif
    const float ax = e.ax, ay = e.ay, bx = e.bx, by = e.by, cx = e.cx, cy = e.cy;
    const float eu = e.eu, ev = e.ev, ew = e.ew;

    // t: plane_t. tmin <= RN_f32(t) iff tmin <= t for float tmin (monotone
    // rounding): the range is tested in double, then t is rounded.
    double dt;
    if (!plane_t(w, v0, v1, v2, dt) || !(dt >= double(tmin) && dt <= double(tmax))) return false;
    // A t beyond the float range is no hit: a hit of t = +-inf reads as a miss in a Hit
    // record, and a tmax of inf would then let every later triangle pass (the closest
    // hit no longer the closest).
    const float ft = float(dt);
    if (!is_finite_f(ft)) return false;
    const float det = add_rn(add_rn(eu, ev), ew);
    const float adet = abs_f(det);
    // Float u, v only when all edge functions are nonzero and nothing is near under-
    // or overflow: 2^-64 <= |det| <= 2^64 (false for NaN and inf). Otherwise redo the
    // edge functions in double; products of floats are exact there and cannot over-
    // or underflow (|x| in [2^-298, 2^256]). The edge signs agree with the float
    // path's (see above), so mixing the two paths keeps the mesh closed.
    if (eu != 0.0f && ev != 0.0f && ew != 0.0f && adet >= 5.42101086e-20f && adet <= 1.84467441e+19f) {
        const float rcp = 1.0f / det;
        out.t = ft;
        out.u = mul_rn(ev, rcp);
        out.v = mul_rn(ew, rcp);
        return true;
    }
    const double du = sub_rn(mul_rn(double(cx), double(by)), mul_rn(double(cy), double(bx)));
    const double dv = sub_rn(mul_rn(double(ax), double(cy)), mul_rn(double(ay), double(cx)));
    const double dw = sub_rn(mul_rn(double(bx), double(ay)), mul_rn(double(by), double(ax)));
    if ((du < 0.0 || dv < 0.0 || dw < 0.0) && (du > 0.0 || dv > 0.0 || dw > 0.0)) return false;
    const double ddet = add_rn(add_rn(du, dv), dw);
    // 0: the ray in the triangle's plane. NaN or +-inf: a sheared coordinate overflowed
    // float (v - o beyond ~2^127), where u, v would be NaN (inf / inf): no hit, as
    // spec/rays.md allows where v - o overflows.
    if (ddet == 0.0 || !(abs_d(ddet) <= 1.7976931348623157e308)) return false;
    out.t = ft;
    out.u = float(dv / ddet);
    out.v = float(dw / ddet);
    return true;
}

/// t, u, v of a hit that watertight_range_interval certified (kInside, and the edge
/// functions nonzero with agreeing signs): what intersect_triangle_watertight reports for
/// it, bit for bit, without the tests that cannot fail for it (plane_t's bound on n.d and
/// range, the double recomputation of zero edge functions). The same operations as
/// plane_t's num and den and as its u, v paths; on the device a deferred hit is finished
/// with it at refill time, where the whole test's temporaries (plane_t's bound keeps six
/// products live) pushed the kernel past its registers. tests/traverse/triangle_range_test.cpp
/// compares it with the whole test on every certified case.
CWBVH_HD CWBVH_INLINE TriangleHit watertight_finish(const WatertightRay& w, const float* v0, const float* v1,
                                                    const float* v2) {
    const double px = v0[0], py = v0[1], pz = v0[2];
    const double e1x = sub_rn(double(v1[0]), px), e1y = sub_rn(double(v1[1]), py);
    const double e1z = sub_rn(double(v1[2]), pz);
    const double e2x = sub_rn(double(v2[0]), px), e2y = sub_rn(double(v2[1]), py);
    const double e2z = sub_rn(double(v2[2]), pz);
    const double nx = sub_rn(mul_rn(e1y, e2z), mul_rn(e1z, e2y));
    const double ny = sub_rn(mul_rn(e1z, e2x), mul_rn(e1x, e2z));
    const double nz = sub_rn(mul_rn(e1x, e2y), mul_rn(e1y, e2x));
    const double num = add_rn(
        add_rn(mul_rn(nx, sub_rn(px, double(w.org[0]))), mul_rn(ny, sub_rn(py, double(w.org[1])))),
        mul_rn(nz, sub_rn(pz, double(w.org[2]))));
    const double den = add_rn(add_rn(mul_rn(nx, double(w.dir[0])), mul_rn(ny, double(w.dir[1]))),
                              mul_rn(nz, double(w.dir[2])));
    TriangleHit out;
    out.t = float(num / den);
    WatertightEdges e;
    watertight_edges(w, v0, v1, v2, e);
    const float det = add_rn(add_rn(e.eu, e.ev), e.ew);
    const float adet = abs_f(det);
    if (adet >= 5.42101086e-20f && adet <= 1.84467441e+19f) {
        const float rcp = 1.0f / det;
        out.u = mul_rn(e.ev, rcp);
        out.v = mul_rn(e.ew, rcp);
        return out;
    }
    const double du = sub_rn(mul_rn(double(e.cx), double(e.by)), mul_rn(double(e.cy), double(e.bx)));
    const double dv = sub_rn(mul_rn(double(e.ax), double(e.cy)), mul_rn(double(e.ay), double(e.cx)));
    const double dw = sub_rn(mul_rn(double(e.bx), double(e.ay)), mul_rn(double(e.by), double(e.ax)));
    const double ddet = add_rn(add_rn(du, dv), dw);
    out.u = float(dv / ddet);
    out.v = float(dw / ddet);
    return out;
}

// ---------------------------------------------------------------------------
// Fast test (Moller & Trumbore 1997), no epsilon
// ---------------------------------------------------------------------------

CWBVH_HD CWBVH_INLINE bool intersect_triangle_fast(const Ray& r, const float* v0, const float* v1,
                                                   const float* v2, float tmin, float tmax,
                                                   TriangleHit& out) {
    const float e1[3] = {v1[0] - v0[0], v1[1] - v0[1], v1[2] - v0[2]};
    const float e2[3] = {v2[0] - v0[0], v2[1] - v0[1], v2[2] - v0[2]};
    const float pv[3] = {r.dir[1] * e2[2] - r.dir[2] * e2[1], r.dir[2] * e2[0] - r.dir[0] * e2[2],
                         r.dir[0] * e2[1] - r.dir[1] * e2[0]};
    const float det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    // Only an exact zero is rejected: any absolute threshold would depend on the
    // scene's scale (cwbvh-facts 1.5: tinybvh's 1e-7 occlusion epsilon).
    if (det == 0.0f || !is_finite_f(det)) return false;
    const float inv = 1.0f / det;
    const float tv[3] = {r.org[0] - v0[0], r.org[1] - v0[1], r.org[2] - v0[2]};
    const float u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) * inv;
    if (!(u >= 0.0f && u <= 1.0f)) return false;
    const float qv[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2],
                         tv[0] * e1[1] - tv[1] * e1[0]};
    const float v = (r.dir[0] * qv[0] + r.dir[1] * qv[1] + r.dir[2] * qv[2]) * inv;
    if (!(v >= 0.0f && u + v <= 1.0f)) return false;
    const float t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) * inv;
    if (!(t >= tmin && t <= tmax) || !is_finite_f(t)) return false;  // +-inf: no hit (see the watertight test)
    out.t = t;
    out.u = u;
    out.v = v;
    return true;
}

// ---------------------------------------------------------------------------
// Compile-time selection
// ---------------------------------------------------------------------------

template <TriangleTest kTest>
struct TriangleIntersector;

template <>
struct TriangleIntersector<TriangleTest::kWatertight> {
    WatertightRay w;
    CWBVH_HD explicit TriangleIntersector(const Ray& r) : w(make_watertight_ray(r)) {}
    CWBVH_HD bool operator()(const TriangleRecord& tri, float tmin, float tmax, TriangleHit& out) const {
        return intersect_triangle_watertight(w, tri.v0, tri.v1, tri.v2, tmin, tmax, out);
    }
    /// The same test with the origin read from `org`, an array holding the same values
    /// (the GPU lane passes its NodeRay's: the copy in w is then never read and takes no
    /// registers).
    CWBVH_HD TriangleIntersector with_org(const float org[3]) const {
        TriangleIntersector t = *this;
        for (int a = 0; a < 3; ++a) t.w.org[a] = org[a];
        return t;
    }
};

template <>
struct TriangleIntersector<TriangleTest::kFast> {
    Ray r;
    CWBVH_HD explicit TriangleIntersector(const Ray& ray) : r(ray) {}
    CWBVH_HD bool operator()(const TriangleRecord& tri, float tmin, float tmax, TriangleHit& out) const {
        return intersect_triangle_fast(r, tri.v0, tri.v1, tri.v2, tmin, tmax, out);
    }
    CWBVH_HD TriangleIntersector with_org(const float org[3]) const {
        TriangleIntersector t = *this;
        for (int a = 0; a < 3; ++a) t.r.org[a] = org[a];
        return t;
    }
};

}  // namespace cwbvh
