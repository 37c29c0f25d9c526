// Exact brute-force ray/triangle oracle: defines truth for the traversal tests
// (tests/traverse, tests/stress) and for bench/error (cwbvh_bench_error).
// Header-only; depends on format.h and the kernels' ray.h, nothing else (no Embree).
//
// Hit/miss is decided with exact arithmetic: the three edge functions are signed
// volumes det(B, C, D), det(C, A, D), det(A, B, D) with A = v0 - o, B = v1 - o,
// C = v2 - o, D = dir. Their signs are computed exactly with floating-point
// expansions (Shewchuk 1997, "Adaptive Precision Floating-Point Arithmetic and Fast
// Robust Geometric Predicates": Two-Sum, Two-Product, Grow-Expansion with zero
// elimination). Every input is a float, so in double: each difference is exactly a
// two-term expansion; each product of three terms is exact as 4 doubles (no over-
// or underflow: magnitudes stay in [2^-600, 2^400]). A double filter (value vs. an
// error bound) answers first; the expansion runs only when the filter is unsure.
// A ray hits when the three signs agree (zeros allowed: edges and vertices count)
// and are not all zero (a ray in the triangle's plane is a miss, as in the kernels).
// t is then computed in long double from the rounded edge functions; it is used
// for the closest-hit choice with a tolerance (ties are OK).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray.h"

namespace cwbvh::oracle {

inline void two_sum(double a, double b, double& x, double& y) {
    x = a + b;
    const double bv = x - a;
    const double av = x - bv;
    y = (a - av) + (b - bv);
}
inline void two_prod(double a, double b, double& x, double& y) {
    x = a * b;
    y = std::fma(a, b, -x);  // exact error of the product (no underflow here)
}

/// Nonoverlapping expansion, increasing magnitude, zeros removed.
struct Expansion {
    std::vector<double> c;
    void add(double b) {  // Grow-Expansion with zero elimination
        if (b == 0.0) return;
        double q = b;
        size_t out = 0;
        for (size_t i = 0; i < c.size(); ++i) {
            double x, y;
            two_sum(q, c[i], x, y);
            q = x;
            if (y != 0.0) c[out++] = y;
        }
        c.resize(out);
        if (q != 0.0) c.push_back(q);
    }
    int sign() const { return c.empty() ? 0 : (c.back() > 0 ? 1 : -1); }
    double approx() const {
        double s = 0;
        for (double v : c) s += v;
        return s;
    }
};

struct Exact2 {  // a float difference a - b as an exact two-term expansion
    double h, l;
};
inline Exact2 exact_diff(float a, float b) {
    Exact2 r;
    two_sum(double(a), -double(b), r.h, r.l);
    return r;
}

/// Exact sign and approximate value of det(A, B, D) = A . (B x D).
inline int exact_det_sign(const Exact2* A, const Exact2* B, const float* D, double& value) {
    // Double filter: each term a_i b_j d_k is computed with relative error <= 3 eps
    // (plus the dropped low parts, <= eps relative each); the sum of 6 terms adds
    // 5 eps of the absolute sum. 16 eps of the absolute sum is a safe bound.
    static const int perm[6][4] = {{0, 1, 2, 1}, {1, 2, 0, 1}, {2, 0, 1, 1},
                                   {0, 2, 1, -1}, {1, 0, 2, -1}, {2, 1, 0, -1}};
    double sum = 0.0, abs_sum = 0.0;
    for (const auto& p : perm) {
        const double t = A[p[0]].h * B[p[1]].h * double(D[p[2]]);
        sum += p[3] * t;
        abs_sum += std::fabs(t) + std::fabs(A[p[0]].l * B[p[1]].h * double(D[p[2]])) +
                   std::fabs(A[p[0]].h * B[p[1]].l * double(D[p[2]])) +
                   std::fabs(A[p[0]].l * B[p[1]].l * double(D[p[2]]));
    }
    value = sum;
    const double bound = 16.0 * 1.1102230246251565e-16 * abs_sum + 1e-300;
    if (sum > bound) return 1;
    if (sum < -bound) return -1;
    // Exact: 6 permutations x 4 (hi/lo pairs) x 4 doubles per product of three.
    Expansion e;
    for (const auto& p : perm) {
        const double as[2] = {A[p[0]].h, A[p[0]].l};
        const double bs[2] = {B[p[1]].h, B[p[1]].l};
        for (double a : as) {
            for (double b : bs) {
                double x, y, r1, r2, r3, r4;
                two_prod(a, b, x, y);
                two_prod(x, double(D[p[2]]), r1, r2);
                two_prod(y, double(D[p[2]]), r3, r4);
                e.add(p[3] * r1);
                e.add(p[3] * r2);
                e.add(p[3] * r3);
                e.add(p[3] * r4);
            }
        }
    }
    value = e.approx();
    return e.sign();
}

struct OracleTriangle {
    bool hit = false;
    long double t = 0;
};

/// The signed volumes of the ray against the triangle's edges (the scaled barycentrics of
/// the line's crossing): exact signs, approximate values. All three signs 0: the ray lies
/// in the triangle's plane.
struct EdgeVolumes {
    int su = 0, sv = 0, sw = 0;
    double u = 0, v = 0, w = 0;
    bool coplanar() const { return su == 0 && sv == 0 && sw == 0; }
};

inline EdgeVolumes edge_volumes(const Ray& r, const float* v0, const float* v1, const float* v2) {
    Exact2 A[3], B[3], C[3];
    for (int a = 0; a < 3; ++a) {
        A[a] = exact_diff(v0[a], r.org[a]);
        B[a] = exact_diff(v1[a], r.org[a]);
        C[a] = exact_diff(v2[a], r.org[a]);
    }
    EdgeVolumes e;
    e.su = exact_det_sign(B, C, r.dir, e.u);
    e.sv = exact_det_sign(C, A, r.dir, e.v);
    e.sw = exact_det_sign(A, B, r.dir, e.w);
    return e;
}

/// Does the line org + t*dir meet the triangle, and at which t (any t, no range).
inline OracleTriangle oracle_triangle(const Ray& r, const float* v0, const float* v1, const float* v2) {
    const EdgeVolumes e = edge_volumes(r, v0, v1, v2);
    const int su = e.su, sv = e.sv, sw = e.sw;
    const double u = e.u, v = e.v, w = e.w;
    OracleTriangle out;
    if ((su < 0 || sv < 0 || sw < 0) && (su > 0 || sv > 0 || sw > 0)) return out;
    if (su == 0 && sv == 0 && sw == 0) return out;
    const long double s = (long double)u + v + w;
    long double num = 0, den = 0;
    for (int a = 0; a < 3; ++a) {
        const long double p = ((long double)u * v0[a] + (long double)v * v1[a] + (long double)w * v2[a]) / s;
        num += (p - r.org[a]) * r.dir[a];
        den += (long double)r.dir[a] * r.dir[a];
    }
    out.hit = true;
    out.t = num / den;
    return out;
}

struct OracleResult {
    bool hit = false;
    long double t = INFINITY;
    uint32_t prim = kMissPrim;
    std::vector<uint32_t> ties;  ///< prims with t within tol of the closest (incl. prim)
    bool near_range_end = false; ///< some hit lies within tol of tmin or tmax: skip strict checks
    long double tol = 0;
};

/// Brute force over all triangles (prim = TriangleRecord::prim). tol: absolute t
/// tolerance for ties and for the range ends; by default derived from the
/// triangles' and the origin's magnitude (float precision, 2^-18 relative).
inline OracleResult oracle_trace(const Ray& r, const TriangleRecord* tris, size_t n, long double tol = -1) {
    OracleResult res;
    if (!ray_is_traceable(r)) return res;
    if (tol < 0) {
        long double m = 0, dl = 0;
        for (int a = 0; a < 3; ++a) {
            m = std::max(m, std::fabs((long double)r.org[a]));
            dl = std::max(dl, std::fabs((long double)r.dir[a]));
        }
        long double ext = 0;
        for (size_t i = 0; i < n; ++i)
            for (int a = 0; a < 3; ++a)
                ext = std::max({ext, std::fabs((long double)tris[i].v0[a]), std::fabs((long double)tris[i].v1[a]),
                                std::fabs((long double)tris[i].v2[a])});
        tol = (m + ext) / dl * 3.814697265625e-06L;  // 2^-18
    }
    res.tol = tol;
    std::vector<std::pair<long double, uint32_t>> hits;
    for (size_t i = 0; i < n; ++i) {
        const OracleTriangle o = oracle_triangle(r, tris[i].v0, tris[i].v1, tris[i].v2);
        if (!o.hit) continue;
        if (std::fabs(o.t - r.tmin) <= tol || std::fabs(o.t - r.tmax) <= tol) res.near_range_end = true;
        if (o.t < r.tmin || o.t > r.tmax) continue;
        // A t beyond the float range is no hit (spec/rays.md): what the float RN(t) of the
        // traversal would make +-inf. Near the edge, the traversal's t rounds too: flagged.
        constexpr long double kFltMax = 3.40282346638528859811704183484516925e+38L;
        if (std::fabs(o.t) > kFltMax * (1 + 1e-6L)) continue;
        if (std::fabs(o.t) > kFltMax * (1 - 1e-6L)) res.near_range_end = true;
        hits.push_back({o.t, tris[i].prim});
        if (o.t < res.t) {
            res.t = o.t;
            res.prim = tris[i].prim;
            res.hit = true;
        }
    }
    for (const auto& h : hits)
        if (h.first <= res.t + tol) res.ties.push_back(h.second);
    return res;
}

/// t of the line's intersection with a given triangle (for checking a reported hit).
inline bool oracle_hits_prim(const Ray& r, const TriangleRecord* tris, size_t n, uint32_t prim, long double& t) {
    for (size_t i = 0; i < n; ++i) {
        if (tris[i].prim != prim) continue;
        const OracleTriangle o = oracle_triangle(r, tris[i].v0, tris[i].v1, tris[i].v2);
        if (o.hit) {
            t = o.t;
            return true;
        }
    }
    return false;
}

}  // namespace cwbvh::oracle

// The tests and bench/error were written against cwbvh::test::oracle_trace etc.;
// they keep working unchanged until they say cwbvh::oracle:: themselves.
namespace cwbvh::test {
using namespace cwbvh::oracle;
}  // namespace cwbvh::test
