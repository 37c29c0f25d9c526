// Instance transforms on the host (spec 3.10): inverse, condition number,
// conservative world box, rules 6021-6023.
#include "cwbvh/format/transform_host.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <cstdio>
#include <string>

#include "cwbvh/format/float_round.h"

namespace cwbvh {
namespace {

bool finite_3x4(const float m[3][4]) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
            if (!std::isfinite(m[r][c])) return false;
    return true;
}

/// Largest absolute row sum of the 3x3 part (the infinity norm).
double inf_norm(const double a[3][4]) {
    double n = 0;
    for (int r = 0; r < 3; ++r) n = std::max(n, std::fabs(a[r][0]) + std::fabs(a[r][1]) + std::fabs(a[r][2]));
    return n;
}

constexpr double kFloatMax = 3.4028234663852886e38;  // FLT_MAX

std::string num(double v) {
    char b[40];
    std::snprintf(b, sizeof b, "%.9g", v);
    return b;
}

}  // namespace

double affine_determinant(const float m[3][4]) {
    // Each product of two floats is exact in double (48 significant bits).
    const double c0 = double(m[1][1]) * m[2][2] - double(m[1][2]) * m[2][1];
    const double c1 = double(m[1][2]) * m[2][0] - double(m[1][0]) * m[2][2];
    const double c2 = double(m[1][0]) * m[2][1] - double(m[1][1]) * m[2][0];
    return double(m[0][0]) * c0 + double(m[0][1]) * c1 + double(m[0][2]) * c2;
}

bool invert_affine(const float m[3][4], double inv[3][4]) {
    if (!finite_3x4(m)) return false;
    const double det = affine_determinant(m);
    if (det == 0.0 || !std::isfinite(det)) return false;
    auto a = [&](int r, int c) { return double(m[r][c]); };
    // adj(A)[r][c] = cofactor(c, r); products exact, one rounding per difference.
    const double adj[3][3] = {
        {a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1), a(0, 2) * a(2, 1) - a(0, 1) * a(2, 2),
         a(0, 1) * a(1, 2) - a(0, 2) * a(1, 1)},
        {a(1, 2) * a(2, 0) - a(1, 0) * a(2, 2), a(0, 0) * a(2, 2) - a(0, 2) * a(2, 0),
         a(0, 2) * a(1, 0) - a(0, 0) * a(1, 2)},
        {a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0), a(0, 1) * a(2, 0) - a(0, 0) * a(2, 1),
         a(0, 0) * a(1, 1) - a(0, 1) * a(1, 0)},
    };
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) inv[r][c] = adj[r][c] / det;
        inv[r][3] = -(inv[r][0] * a(0, 3) + inv[r][1] * a(1, 3) + inv[r][2] * a(2, 3));
    }
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
            if (!std::isfinite(inv[r][c])) return false;
    return true;
}

double condition_number(const float m[3][4]) {
    double inv[3][4];
    if (!invert_affine(m, inv)) return INFINITY;
    double a[3][4];
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) a[r][c] = m[r][c];
    const double k = inf_norm(a) * inf_norm(inv);
    return std::isfinite(k) ? k : INFINITY;
}

Result check_instance_transforms(const float o2w[3][4], const float w2o[3][4]) {
    if (!finite_3x4(o2w)) return fail(rule::kInstNonFinite, "object_to_world is not finite");
    if (!finite_3x4(w2o)) return fail(rule::kInstNonFinite, "world_to_object is not finite");
    double x[3][4];
    const double kappa = condition_number(o2w);
    // Written as !(<=) so that a NaN (cannot happen after the finite checks) also fails.
    if (!(kappa <= kMaxTransformCondition) || !invert_affine(o2w, x))
        return fail(rule::kInstCondition, "object_to_world has condition number " + num(kappa) +
                                              " (singular or above the limit 2^20)");
    double lin_max = 0;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) lin_max = std::max(lin_max, std::fabs(x[r][c]));
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c)
            if (!(std::fabs(double(w2o[r][c]) - x[r][c]) <= kInverseTolerance * lin_max))
                return fail(rule::kInstInverse, "world_to_object[" + std::to_string(r) + "][" + std::to_string(c) +
                                                    "] = " + num(w2o[r][c]) + " but the inverse is " + num(x[r][c]));
        double scale = 0;  // the translation's magnitude before cancellation
        for (int c = 0; c < 3; ++c) scale += std::fabs(x[r][c] * double(o2w[c][3]));
        if (!(std::fabs(double(w2o[r][3]) - x[r][3]) <= kInverseTolerance * scale))
            return fail(rule::kInstInverse, "world_to_object[" + std::to_string(r) + "][3] = " + num(w2o[r][3]) +
                                                " but the inverse is " + num(x[r][3]));
    }
    return Result::success();
}

void transform_box(const float m[3][4], const float lo[3], const float hi[3], float out_lo[3], float out_hi[3]) {
    double wlo[3] = {INFINITY, INFINITY, INFINITY}, whi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int corner = 0; corner < 8; ++corner) {
        const double p[3] = {(corner & 1) ? hi[0] : lo[0], (corner & 2) ? hi[1] : lo[1], (corner & 4) ? hi[2] : lo[2]};
        for (int r = 0; r < 3; ++r) {
            // Products of two floats are exact in double; the three additions round (each by at
            // most 2^-53 of the partial sum, which is at most `mag`), so the sum lies within
            // 3 * 2^-53 * mag of the exact image. Widening by 2^-50 * mag covers that and the
            // rounding of the widening itself, and stays far below a float ulp (2^-24).
            const double t0 = double(m[r][0]) * p[0], t1 = double(m[r][1]) * p[1], t2 = double(m[r][2]) * p[2];
            const double t3 = m[r][3];
            const double v = ((t0 + t1) + t2) + t3;
            const double mag = std::fabs(t0) + std::fabs(t1) + std::fabs(t2) + std::fabs(t3);
            const double err = std::ldexp(mag, -50);
            wlo[r] = std::min(wlo[r], v - err);
            whi[r] = std::max(whi[r], v + err);
        }
    }
    // Outward to float: lo rounds down, hi rounds up (a box rounded to nearest could cut
    // off a corner, and a ray grazing that corner would miss the instance).
    for (int r = 0; r < 3; ++r) {
        out_lo[r] = float_round_down(wlo[r]);
        out_hi[r] = float_round_up(whi[r]);
    }
}

void identity_transform(float m[3][4]) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) m[r][c] = r == c ? 1.0f : 0.0f;
}

Expected<InstanceRecord> make_instance(const float object_to_world[3][4], const MeshRecord& mesh,
                                       uint32_t mesh_index, uint32_t source_node) {
    auto bad = [](uint32_t rule_id, const std::string& what) {
        return Result::fail(Status::kInvalidArgument, rule_id, "instance transform: " + what);
    };
    InstanceRecord inst{};
    double x[3][4];
    if (!finite_3x4(object_to_world)) return bad(rule::kInstNonFinite, "not finite");
    if (const double k = condition_number(object_to_world); !(k <= kMaxTransformCondition) ||
                                                              !invert_affine(object_to_world, x))
        return bad(rule::kInstCondition, "condition number " + num(k) + " (singular or above the limit 2^20)");
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
            if (!(std::fabs(x[r][c]) <= kFloatMax))
                return bad(rule::kInstNonFinite, "the inverse overflows float");
            inst.object_to_world[r][c] = object_to_world[r][c];
            inst.world_to_object[r][c] = static_cast<float>(x[r][c]);  // RN (round to nearest even)
        }
    if (Result r = check_instance_transforms(inst.object_to_world, inst.world_to_object); !r.ok())
        return bad(r.rule, r.message);  // e.g. an inverse element overflowing float
    inst.mesh = mesh_index;
    inst.source_node = source_node;
    transform_box(object_to_world, mesh.lo, mesh.hi, inst.world_lo, inst.world_hi);
    // Widening for the float ray transform (spec 3.10, "World box"): the traversal
    // moves a ray into object space with the float world_to_object (transform.h:
    // rounded entries, three rounded fmas), an object-space error of about
    // 4 * 2^-24 * ||X||inf * (||x||inf + ||t||inf) for a world point x, i.e. up to
    // cond * 2^-22 * (||x|| + ||t||) in world space: points that far outside the exact
    // image of the mesh box can land in it, and the top level must not cull them
    // (outward). Each axis is widened by cond * 2^-21 * (B + ||t||), B = the largest
    // |world coordinate| the mesh box reaches (twice the bound), then rounded outward.
    // A world-point walk over random transforms finds the tight box too small for
    // ~10 % of them and the widened one never (tests/compiler/two_level_test.cpp). A ray
    // origin far from the instance adds error no box can cover (3.10).
    const double cond = condition_number(object_to_world);
    double box_mag = 0, t_mag = 0;
    for (int r = 0; r < 3; ++r) {
        double row = std::fabs(double(object_to_world[r][3]));
        for (int c = 0; c < 3; ++c)
            row += std::fabs(double(object_to_world[r][c])) *
                   std::max(std::fabs(double(mesh.lo[c])), std::fabs(double(mesh.hi[c])));
        box_mag = std::max(box_mag, row);
        t_mag = std::max(t_mag, std::fabs(double(object_to_world[r][3])));
    }
    const double pad = cond * 0x1p-21 * (box_mag + t_mag);
    for (int a = 0; a < 3; ++a) {
        const double lo = double(inst.world_lo[a]) - pad, hi = double(inst.world_hi[a]) + pad;
        inst.world_lo[a] = float_round_down(lo);  // outward; -inf / +inf beyond float (refused below)
        inst.world_hi[a] = float_round_up(hi);
        if (!std::isfinite(inst.world_lo[a]) || !std::isfinite(inst.world_hi[a]))
            return bad(rule::kInstWorldBox, "the world box of the mesh overflows float");
    }
    return inst;
}

}  // namespace cwbvh
