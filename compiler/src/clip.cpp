// Conservative clipping of a triangle against an axis-aligned slab, shared by
// the SBVH builder (Stich, Friedrich, Dietrich 2009, section 4.3: references
// are split by clipping the triangle, not its box) and Embree's splitPrimitive
// callback (build_embree.cpp).
//
// The triangle part inside a slab lo <= x[axis] <= hi is the convex hull of the
// triangle's vertices inside the slab and of the points where its three edges
// cross the two planes. Every such point is computed once, directly from the
// float input vertices (no clip-after-clip error accumulation), in double,
// with an explicit error bound; the float box is then rounded outward.
//
// Speed (the SBVH's spatial-split binning chops every straddling reference
// at every bin plane it spans, 80% of the build before this was tuned): all
// per-edge quantities that do not depend on the plane (differences, error
// bounds, which edges can cross) are computed once per triangle and axis, and
// outward rounding uses float bit arithmetic instead of libm's nextafterf
// (float_round.h).
// The arithmetic on every value is the same expression as before, so results
// are bitwise unchanged.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <limits>

#include "cwbvh/compiler/build.h"

namespace cwbvh::compiler {
namespace {

// Rounding a double bound to float: float_round_down for a lower bound, float_round_up
// for an upper one (cwbvh/format/float_round.h), never to nearest: a lower bound above
// the exact value (or an upper one below it) leaves a gap a ray can pass through.

struct DBox {
    double lo[3] = {HUGE_VAL, HUGE_VAL, HUGE_VAL};
    double hi[3] = {-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    bool any = false;
    void grow(int j, double v, double err) {
        // v - err rounds to nearest in double; err (16 ulps of the operands'
        // magnitude, see below) exceeds the error of v by > 2x, so the
        // result stays below the exact coordinate even after that rounding.
        lo[j] = std::min(lo[j], v - err);
        hi[j] = std::max(hi[j], v + err);
    }
    void grow(const DBox& b) {
        for (int j = 0; j < 3; ++j) {
            lo[j] = std::min(lo[j], b.lo[j]);
            hi[j] = std::max(hi[j], b.hi[j]);
        }
        any = any || b.any;
    }
};

/// Plane-independent data of one triangle for cuts along `axis`.
struct Edges {
    int axis;
    float emin[3], emax[3];  // edge e's endpoint range along the axis
    double a_axis[3];        // double(a[axis])
    double denom[3];         // double(b[axis]) - a[axis]
    double a[3][3];          // double(a[j])
    double d[3][3];          // double(b[j]) - a[j]
    double err[3][3];        // error bound of the crossing's coordinate j

    Edges(const std::array<Vec3, 3>& tri, int ax) : axis(ax) {
        constexpr double kEps = DBL_EPSILON * 0.5;  // 2^-53, unit roundoff of double
        for (int e = 0; e < 3; ++e) {
            const Vec3& pa = tri[e];
            const Vec3& pb = tri[e == 2 ? 0 : e + 1];
            emin[e] = std::min(pa[axis], pb[axis]);
            emax[e] = std::max(pa[axis], pb[axis]);
            a_axis[e] = double(pa[axis]);
            denom[e] = double(pb[axis]) - pa[axis];
            for (int j = 0; j < 3; ++j) {
                a[e][j] = double(pa[j]);
                d[e][j] = double(pb[j]) - pa[j];
                // p = a + t (b - a): |error| <= ~7 u (|a|+|b|); we use 16 u plus
                // a tiny absolute term so that the bound never underflows to 0.
                err[e][j] = 16.0 * kEps * (std::fabs(double(pa[j])) + std::fabs(double(pb[j]))) + 1e-300;
            }
        }
    }

    /// Conservative double box of the points where the triangle's edges cross
    /// the plane x[axis] = c (only edges with endpoints strictly on both sides;
    /// endpoints on the plane are vertices and handled by the caller).
    DBox cut(float c) const {
        DBox box;
        if (!std::isfinite(c)) return box;
        for (int e = 0; e < 3; ++e) {
            // Strictly on both sides. (The sign of double(a) - c, computed
            // before, is the sign of the exact difference: the same test.)
            if (!(emin[e] < c && c < emax[e])) continue;
            // t in (0,1): relative error <= 3 ulps (two subtractions, one division).
            const double t = (double(c) - a_axis[e]) / denom[e];
            for (int j = 0; j < 3; ++j) {
                if (j == axis) {
                    box.grow(j, c, 0.0);  // the crossing lies exactly on the plane
                    continue;
                }
                box.grow(j, a[e][j] + t * d[e][j], err[e][j]);
            }
            box.any = true;
        }
        return box;
    }
};

/// Float box of `part` restricted to the slab and to `ref`; empty if none.
Aabb finish(const DBox& part, int axis, float slab_lo, float slab_hi, const Aabb& ref) {
    if (!part.any) return Aabb{};
    Aabb out;
    for (int j = 0; j < 3; ++j) {
        out.lo[j] = float_round_down(part.lo[j]);  // outward: down for the lower bound
        out.hi[j] = float_round_up(part.hi[j]);    // outward: up for the upper bound
    }
    // Split axis: the slab planes are floats, so clamping is exact.
    if (out.lo[axis] < slab_lo) out.lo[axis] = slab_lo;
    if (out.hi[axis] > slab_hi) out.hi[axis] = slab_hi;
    // Intersect with the reference's previous box (both are conservative for
    // the part of the triangle they describe, so the intersection is too).
    for (int j = 0; j < 3; ++j) {
        if (out.lo[j] < ref.lo[j]) out.lo[j] = ref.lo[j];
        if (out.hi[j] > ref.hi[j]) out.hi[j] = ref.hi[j];
        if (!(out.lo[j] <= out.hi[j])) return Aabb{};  // nothing of this reference on this side
    }
    return out;
}

}  // namespace

void chop_triangle(const std::array<Vec3, 3>& tri, int axis, const float* planes, int slabs,
                   const Aabb& ref, Aabb* out) {
    const Edges edges(tri, axis);
    // Each plane's edge crossings are computed once and shared by the two
    // slabs it bounds.
    DBox lower = edges.cut(planes[0]);
    for (int s = 0; s < slabs; ++s) {
        const float lo = planes[s], hi = planes[s + 1];
        const DBox upper = edges.cut(hi);
        DBox part = lower;
        part.grow(upper);
        // Vertices inside the slab: exact (float -> double is exact).
        for (int k = 0; k < 3; ++k) {
            const float c = tri[k][axis];
            if (c >= lo && c <= hi) {
                for (int j = 0; j < 3; ++j) part.grow(j, tri[k][j], 0.0);
                part.any = true;
            }
        }
        out[s] = finish(part, axis, lo, hi, ref);
        lower = upper;
    }
}

void chop_triangle_estimate(const std::array<Vec3, 3>& tri, int axis, const float* planes, int slabs,
                            const Aabb& ref, Aabb* out) {
    // Plain float arithmetic: the crossing points are off by a few ulps in
    // either direction, which only moves the SAH estimate of a candidate
    // plane; no box from here is ever stored. A crossing of edge a -> b at
    // plane c is a + t (b - a) with t = (c - a[axis]) * (1 / (b[axis] - a[axis])),
    // each step one float operation (the values tests/build/clip_test.cpp
    // checks against). Its axis coordinate is c itself, so only the other two
    // coordinates u, v are computed.
    const int u = axis == 0 ? 1 : 0, v = axis == 2 ? 1 : 2;
    struct Edge {
        float emin, emax, a_axis, inv, au, du, av, dv;
    };
    Edge edge[3];
    for (int e = 0; e < 3; ++e) {
        const Vec3& a = tri[e];
        const Vec3& b = tri[e == 2 ? 0 : e + 1];
        Edge& E = edge[e];
        E.emin = std::min(a[axis], b[axis]);
        E.emax = std::max(a[axis], b[axis]);
        E.inv = E.emax > E.emin ? 1.0f / (b[axis] - a[axis]) : 0.0f;
        E.a_axis = a[axis];
        E.au = a[u];
        E.du = b[u] - a[u];
        E.av = a[v];
        E.dv = b[v] - a[v];
    }
    constexpr float kInf = std::numeric_limits<float>::infinity();
    /// Box of the crossings at one plane: u and v ranges; any = some edge crosses.
    struct Cut {
        float lo_u = kInf, hi_u = -kInf, lo_v = kInf, hi_v = -kInf;
        bool any = false;
    };
    auto cut = [&](float c) {
        Cut k;
        for (const Edge& E : edge) {
            if (!(E.emin < c && c < E.emax)) continue;  // strictly on both sides
            const float t = (c - E.a_axis) * E.inv;
            const float pu = E.au + t * E.du, pv = E.av + t * E.dv;
            k.lo_u = std::min(k.lo_u, pu);
            k.hi_u = std::max(k.hi_u, pu);
            k.lo_v = std::min(k.lo_v, pv);
            k.hi_v = std::max(k.hi_v, pv);
            k.any = true;
        }
        return k;
    };
    // The part of slab s is kept in named scalars (u, v, axis order) and
    // written to out[s] field by field: assembling it in an Aabb and copying
    // that made every slab wait on a failed store-to-load forward.
    const float ref_lo_u = ref.lo[u], ref_hi_u = ref.hi[u], ref_lo_v = ref.lo[v], ref_hi_v = ref.hi[v];
    const float ref_lo_a = ref.lo[axis], ref_hi_a = ref.hi[axis];
    Cut lower = cut(planes[0]);
    for (int s = 0; s < slabs; ++s) {
        const float lo = planes[s], hi = planes[s + 1];
        const Cut upper = cut(hi);
        float lu = std::min(lower.lo_u, upper.lo_u), hu = std::max(lower.hi_u, upper.hi_u);
        float lv = std::min(lower.lo_v, upper.lo_v), hv = std::max(lower.hi_v, upper.hi_v);
        float la = kInf, ha = -kInf;
        if (lower.any) la = ha = lo;
        if (upper.any) {
            la = std::min(la, hi);
            ha = std::max(ha, hi);
        }
        for (int k = 0; k < 3; ++k) {  // vertices inside the slab
            const float c = tri[k][axis];
            if (c >= lo && c <= hi) {
                la = std::min(la, c);
                ha = std::max(ha, c);
                lu = std::min(lu, tri[k][u]);
                hu = std::max(hu, tri[k][u]);
                lv = std::min(lv, tri[k][v]);
                hv = std::max(hv, tri[k][v]);
            }
        }
        lu = std::max(lu, ref_lo_u);
        hu = std::min(hu, ref_hi_u);
        lv = std::max(lv, ref_lo_v);
        hv = std::min(hv, ref_hi_v);
        la = std::max(std::max(la, ref_lo_a), lo);
        ha = std::min(std::min(ha, ref_hi_a), hi);
        Aabb& o = out[s];
        if (lu <= hu && lv <= hv && la <= ha) {
            o.lo[u] = lu;
            o.hi[u] = hu;
            o.lo[v] = lv;
            o.hi[v] = hv;
            o.lo[axis] = la;
            o.hi[axis] = ha;
        } else {
            for (int j = 0; j < 3; ++j) {
                o.lo[j] = kInf;
                o.hi[j] = -kInf;
            }
        }
        lower = upper;
    }
}

Aabb clip_triangle(const std::array<Vec3, 3>& tri, int axis, float slab_lo, float slab_hi,
                   const Aabb& ref) {
    const float planes[2] = {slab_lo, slab_hi};
    Aabb out;
    chop_triangle(tri, axis, planes, 1, ref, &out);
    return out;
}

}  // namespace cwbvh::compiler
