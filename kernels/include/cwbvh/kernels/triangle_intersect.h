// Ray-triangle tests, chosen at compile time by TriangleTest.
//   kWatertight: Woop, Benthin, Wald 2013, "Watertight Ray/Triangle Intersection"
//                (JCGT 2(1)), with the paper's double-precision fallback.
//   kFast:       Moller, Trumbore 1997, with no absolute epsilon anywhere (nothing
//                depends on the scene's scale); not watertight.
// Both accept hits with tmin <= t <= tmax (closed) and report u, v as the
// barycentric weights of v1 and v2. A triangle whose plane contains the ray
// (det == 0) is a miss in both.
#pragma once

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

/// Per-ray shear constants (paper, section 3): kz = dominant axis of dir, kx, ky
/// the other two, swapped when dir[kz] < 0 to keep the winding; the shear maps dir
/// to (0, 0, dir[kz]).
struct WatertightRay {
    float ox, oy, oz;  ///< org[kx], org[ky], org[kz]: permuted once per ray
    float dx, dy, dz;  ///< dir[kx], dir[ky], dir[kz] (plane_t)
    uint32_t k;        ///< kx | ky << 8 | kz << 16: one register (issue 10's budget)
    CWBVH_HD int kx() const { return int(k & 0xFFu); }
    CWBVH_HD int ky() const { return int((k >> 8) & 0xFFu); }
    CWBVH_HD int kz() const { return int(k >> 16); }
    float sx, sy;
};

/// v[k] for k in 0..2. On the device a chain of selects: an indexed read of a
/// triangle held in registers would force it into local memory. On the host the
/// triangle is in memory anyway and an indexed load is one instruction.
CWBVH_HD CWBVH_INLINE float pick3(const float* v, int k) {
#if defined(__CUDA_ARCH__)
    return k == 0 ? v[0] : (k == 1 ? v[1] : v[2]);
#else
    return v[k];
#endif
}

CWBVH_HD CWBVH_INLINE WatertightRay make_watertight_ray(const Ray& r) {
    WatertightRay w;
    const float ax = abs_f(r.dir[0]), ay = abs_f(r.dir[1]), az = abs_f(r.dir[2]);
    const int kz = (ax > ay) ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    const float dz = pick3(r.dir, kz);
    if (dz < 0.0f) {
        const int tmp = kx;
        kx = ky;
        ky = tmp;
    }
    w.k = uint32_t(kx) | uint32_t(ky) << 8 | uint32_t(kz) << 16;
    // dir[kz] != 0 for a traceable ray. These roundings are shared by every triangle
    // the ray meets, so they cannot open a crack between neighbours.
    w.ox = pick3(r.org, w.kx());
    w.oy = pick3(r.org, w.ky());
    w.oz = pick3(r.org, w.kz());
    w.dx = pick3(r.dir, w.kx());
    w.dy = pick3(r.dir, w.ky());
    w.dz = dz;
    w.sx = w.dx / dz;
    w.sy = w.dy / dz;
    return w;
}

/// Hit distance: t = n.(v0 - o) / n.d, n = (v1 - v0) x (v2 - v0), in double from the
/// float inputs (axes permuted as in w: num and den flip sign alike). Not the
/// paper's T / det: its float sheared z and edge functions (cancelling near an edge)
/// err by ~u |v - o|, so its t was off by ~u |v - o| / cos, far more than ulps of t
/// (0.3-0.7 % for a sponza bounce ray 0.027 from its hit, 7 from the far vertices);
/// the box tests bound the exact t with 2^-21 slack, so a larger error let a visit
/// order cull the subtree of the closest hit (BVH2 != CWBVH). Here float differences
/// are exact in double (or rounded once), products and sums round to nearest at
/// 2^-53, so the relative error is ~2^-52 x the cancellation |v - o| / (t cos)
/// (~2^11 on that ray): float(t) is within 1 ulp of the exact t up to ~2^28.
/// Nearest rounding everywhere (mul_rn/add_rn/sub_rn: never contracted; IEEE '/'),
/// so host and device agree bitwise. False when the ray is parallel to the plane.
CWBVH_HD CWBVH_INLINE bool plane_t(const WatertightRay& w, const float* v0, const float* v1, const float* v2,
                                   double& t) {
    const double px = pick3(v0, w.kx()), py = pick3(v0, w.ky()), pz = pick3(v0, w.kz());
    const double e1x = sub_rn(double(pick3(v1, w.kx())), px), e1y = sub_rn(double(pick3(v1, w.ky())), py);
    const double e1z = sub_rn(double(pick3(v1, w.kz())), pz);
    const double e2x = sub_rn(double(pick3(v2, w.kx())), px), e2y = sub_rn(double(pick3(v2, w.ky())), py);
    const double e2z = sub_rn(double(pick3(v2, w.kz())), pz);
    const double nx = sub_rn(mul_rn(e1y, e2z), mul_rn(e1z, e2y));
    const double ny = sub_rn(mul_rn(e1z, e2x), mul_rn(e1x, e2z));
    const double nz = sub_rn(mul_rn(e1x, e2y), mul_rn(e1y, e2x));
    const double num = add_rn(add_rn(mul_rn(nx, sub_rn(px, double(w.ox))), mul_rn(ny, sub_rn(py, double(w.oy)))),
                              mul_rn(nz, sub_rn(pz, double(w.oz))));
    const double den = add_rn(add_rn(mul_rn(nx, double(w.dx)), mul_rn(ny, double(w.dy))), mul_rn(nz, double(w.dz)));
    if (den == 0.0 || den != den) return false;
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
    // Vertices relative to the origin, then sheared.
    const float a_kx = sub_rn(pick3(v0, w.kx()), w.ox), a_ky = sub_rn(pick3(v0, w.ky()), w.oy);
    const float a_kz = sub_rn(pick3(v0, w.kz()), w.oz);
    const float b_kx = sub_rn(pick3(v1, w.kx()), w.ox), b_ky = sub_rn(pick3(v1, w.ky()), w.oy);
    const float b_kz = sub_rn(pick3(v1, w.kz()), w.oz);
    const float c_kx = sub_rn(pick3(v2, w.kx()), w.ox), c_ky = sub_rn(pick3(v2, w.ky()), w.oy);
    const float c_kz = sub_rn(pick3(v2, w.kz()), w.oz);
    e.ax = sub_rn(a_kx, mul_rn(w.sx, a_kz));
    e.ay = sub_rn(a_ky, mul_rn(w.sy, a_kz));
    e.bx = sub_rn(b_kx, mul_rn(w.sx, b_kz));
    e.by = sub_rn(b_ky, mul_rn(w.sy, b_kz));
    e.cx = sub_rn(c_kx, mul_rn(w.sx, c_kz));
    e.cy = sub_rn(c_ky, mul_rn(w.sy, c_kz));

    // Scaled barycentrics (edge functions).
    e.eu = sub_rn(mul_rn(e.cx, e.by), mul_rn(e.cy, e.bx));
    e.ev = sub_rn(mul_rn(e.ax, e.cy), mul_rn(e.ay, e.cx));
    e.ew = sub_rn(mul_rn(e.bx, e.ay), mul_rn(e.by, e.ax));
    // Exact-sign early out (NaN from inf-inf fails both comparisons and goes on).
    return !((e.eu < 0.0f || e.ev < 0.0f || e.ew < 0.0f) && (e.eu > 0.0f || e.ev > 0.0f || e.ew > 0.0f));
}

/// The watertight test's second stage, in float: true when the hit distance T of the
/// triangle's plane lies certainly outside [tmin, tmax] (a miss, decided without
/// double precision); false when float cannot decide (the caller then runs plane_t in
/// double, as before). Most triangles whose edge signs agree lie behind the closest hit
/// found so far, and this stage rejects them in about 50 float instructions instead of
/// the double path's 200 (issue 18).
///
/// Exact quantities (axes permuted as in w; o, d the ray): E1 = v1 - v0, E2 = v2 - v0,
/// N = E1 x E2, A = v0 - o, NUM = N.A, DEN = N.d, T = NUM / DEN (plane_t computes the
/// same T). The float values below carry these bounds (u = 2^-24, every operation
/// rounded to nearest, fma_rn rounding once; first order, the second-order terms are
/// below u^2 of the same sums):
///   e1, e2, a: relative error <= u each (a difference that is subnormal is exact);
///   n_i = fma(e1_j, e2_k, -RN(e1_k e2_j)): |n_i - N_i| <= 4u P_i + 2^-149,
///     P_i = |e1_j e2_k| + |e1_k e2_j| (computed as fma(|e1_j|, |e2_k|, |RN(e1_k e2_j)|));
///   num = fma-dot(n, a): |num - NUM| <= (3u + 4u + u) sum P_i |a_i| + 2^-149 (sum |a_i| + 2);
///   den = fma-dot(n, d) (d exact): |den - DEN| <= 7u sum P_i |d_i| + 2^-149 (sum |d_i| + 2),
///     sum |d_i| <= 3 |d_kz| (kz is the dominant axis);
/// where the 2^-149 terms cover products and sums that land in the subnormal range
/// (absolute error <= 2^-150 each). Slack: en = 2^-20 M_num + 2^-146 (sum |a_i| + 1)
/// and ed = 2^-20 M_den + 2^-144 |d_kz| + 2^-146, M = the computed sums of P_i |.|:
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
    const float px0 = pick3(v0, w.kx()), py0 = pick3(v0, w.ky()), pz0 = pick3(v0, w.kz());
    const float e1x = sub_rn(pick3(v1, w.kx()), px0), e1y = sub_rn(pick3(v1, w.ky()), py0);
    const float e1z = sub_rn(pick3(v1, w.kz()), pz0);
    const float e2x = sub_rn(pick3(v2, w.kx()), px0), e2y = sub_rn(pick3(v2, w.ky()), py0);
    const float e2z = sub_rn(pick3(v2, w.kz()), pz0);
    const float ax = sub_rn(px0, w.ox), ay = sub_rn(py0, w.oy), az = sub_rn(pz0, w.oz);
    const float mx = mul_rn(e1z, e2y), my = mul_rn(e1x, e2z), mz = mul_rn(e1y, e2x);
    const float nx = fma_rn(e1y, e2z, -mx), ny = fma_rn(e1z, e2x, -my), nz = fma_rn(e1x, e2y, -mz);
    const float Px = fma_rn(abs_fm(e1y), abs_fm(e2z), abs_fm(mx));
    const float Py = fma_rn(abs_fm(e1z), abs_fm(e2x), abs_fm(my));
    const float Pz = fma_rn(abs_fm(e1x), abs_fm(e2y), abs_fm(mz));
    if (!(add_rn(add_rn(Px, Py), Pz) < 8.5070591730234616e+37f)) return false;  // 2^126; NaN
    const float num = fma_rn(nx, ax, fma_rn(ny, ay, mul_rn(nz, az)));
    const float den = fma_rn(nx, w.dx, fma_rn(ny, w.dy, mul_rn(nz, w.dz)));
    const float Mn = fma_rn(Px, abs_fm(ax), fma_rn(Py, abs_fm(ay), mul_rn(Pz, abs_fm(az))));
    const float Md = fma_rn(Px, abs_fm(w.dx), fma_rn(Py, abs_fm(w.dy), mul_rn(Pz, abs_fm(w.dz))));
    const float sa = add_rn(add_rn(abs_fm(ax), abs_fm(ay)), abs_fm(az));
    const float en = fma_rn(Mn, 9.5367431640625e-07f, fma_rn(sa, 1.1210387714598537e-44f, 1.1210387714598537e-44f));
    const float ed = fma_rn(Md, 9.5367431640625e-07f, fma_rn(abs_fm(w.dz), 4.4841550858394146e-44f, 1.1210387714598537e-44f));
    const float dp = abs_fm(den);
    const float np = bits_to_float(float_to_bits(num) ^ (float_to_bits(den) & 0x80000000u));
    if (!(dp > ed)) return false;  // the sign of DEN is not certain (or NaN)
    const bool far = tmax >= 0.0f && sub_rn(np, en) > mul_rn(tmax, add_rn(dp, ed));
    const bool near = tmin >= 0.0f && add_rn(np, en) < mul_rn(tmin, sub_rn(dp, ed));
    return far || near;
}

CWBVH_HD CWBVH_INLINE bool intersect_triangle_watertight(const WatertightRay& w, const float* v0,
                                                         const float* v1, const float* v2,
                                                         float tmin, float tmax, TriangleHit& out) {
    WatertightEdges e;
    if (!watertight_edges(w, v0, v1, v2, e)) return false;
    if (watertight_range_miss(w, v0, v1, v2, tmin, tmax)) return false;
    const float ax = e.ax, ay = e.ay, bx = e.bx, by = e.by, cx = e.cx, cy = e.cy;
    const float eu = e.eu, ev = e.ev, ew = e.ew;

    // t: plane_t. tmin <= RN_f32(t) iff tmin <= t for float tmin (monotone
    // rounding): the range is tested in double, then t is rounded.
    double dt;
    if (!plane_t(w, v0, v1, v2, dt) || !(dt >= double(tmin) && dt <= double(tmax))) return false;
    const float det = add_rn(add_rn(eu, ev), ew);
    const float adet = abs_f(det);
    // Float u, v only when all edge functions are nonzero and nothing is near under-
    // or overflow: 2^-64 <= |det| <= 2^64 (false for NaN and inf). Otherwise redo the
    // edge functions in double; products of floats are exact there and cannot over-
    // or underflow (|x| in [2^-298, 2^256]). The edge signs agree with the float
    // path's (see above), so mixing the two paths keeps the mesh closed.
    if (eu != 0.0f && ev != 0.0f && ew != 0.0f && adet >= 5.42101086e-20f && adet <= 1.84467441e+19f) {
        const float rcp = 1.0f / det;
        out.t = float(dt);
        out.u = mul_rn(ev, rcp);
        out.v = mul_rn(ew, rcp);
        return true;
    }
    const double du = sub_rn(mul_rn(double(cx), double(by)), mul_rn(double(cy), double(bx)));
    const double dv = sub_rn(mul_rn(double(ax), double(cy)), mul_rn(double(ay), double(cx)));
    const double dw = sub_rn(mul_rn(double(bx), double(ay)), mul_rn(double(by), double(ax)));
    if ((du < 0.0 || dv < 0.0 || dw < 0.0) && (du > 0.0 || dv > 0.0 || dw > 0.0)) return false;
    const double ddet = add_rn(add_rn(du, dv), dw);
    if (ddet == 0.0 || ddet != ddet) return false;  // ray in the triangle's plane, or NaN
    out.t = float(dt);
    out.u = float(dv / ddet);
    out.v = float(dw / ddet);
    return true;
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
    if (!(t >= tmin && t <= tmax)) return false;
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
};

template <>
struct TriangleIntersector<TriangleTest::kFast> {
    Ray r;
    CWBVH_HD explicit TriangleIntersector(const Ray& ray) : r(ray) {}
    CWBVH_HD bool operator()(const TriangleRecord& tri, float tmin, float tmax, TriangleHit& out) const {
        return intersect_triangle_fast(r, tri.v0, tri.v1, tri.v2, tmin, tmax, out);
    }
};

}  // namespace cwbvh
