// Properties of clip_triangle (compiler/src/clip.cpp): the exact part of the
// triangle inside the slab and the reference box lies inside the float box.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "cwbvh/compiler/build.h"

namespace cwbvh::compiler {
namespace {

using LD = long double;  // 64-bit mantissa: reference points far more exact than the box's margin
using Tri = std::array<Vec3, 3>;
constexpr float kInf = std::numeric_limits<float>::infinity();

bool in_box(const Aabb& b, const LD p[3]) {
    for (int j = 0; j < 3; ++j) {
        if (!(LD(b.lo[j]) <= p[j] && p[j] <= LD(b.hi[j]))) return false;
    }
    return true;
}
bool in_ref(const Aabb& b, const LD p[3]) { return in_box(b, p); }

/// Vertices of the exact slab-clipped polygon (before the reference box):
/// triangle vertices inside the slab plus edge crossings of the planes.
std::vector<std::array<LD, 3>> clipped_polygon(const Tri& t, int axis, float lo, float hi) {
    std::vector<std::array<LD, 3>> pts;
    for (int k = 0; k < 3; ++k) {
        if (t[k][axis] >= lo && t[k][axis] <= hi) pts.push_back({LD(t[k][0]), LD(t[k][1]), LD(t[k][2])});
    }
    for (int e = 0; e < 3; ++e) {
        const Vec3& a = t[e];
        const Vec3& b = t[(e + 1) % 3];
        for (const float c : {lo, hi}) {
            if (!std::isfinite(c)) continue;
            if (!((a[axis] < c && b[axis] > c) || (a[axis] > c && b[axis] < c))) continue;
            const LD tt = (LD(c) - a[axis]) / (LD(b[axis]) - a[axis]);
            std::array<LD, 3> p;
            for (int j = 0; j < 3; ++j) p[j] = (j == axis) ? LD(c) : LD(a[j]) + tt * (LD(b[j]) - a[j]);
            pts.push_back(p);
        }
    }
    return pts;
}

/// Checks one triangle/slab/ref combination; returns the number of checked points.
int check(const Tri& t, int axis, float lo, float hi, const Aabb& ref, std::mt19937_64& rng) {
    const Aabb box = clip_triangle(t, axis, lo, hi, ref);
    int checked = 0;
    // 1. Polygon vertices inside the reference box must be inside the result.
    for (const auto& p : clipped_polygon(t, axis, lo, hi)) {
        if (!in_ref(ref, p.data())) continue;
        EXPECT_FALSE(box.empty()) << "point of the part lost: empty result";
        EXPECT_TRUE(in_box(box, p.data()));
        ++checked;
    }
    // 2. Random points of the triangle inside slab and reference box.
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int s = 0; s < 64; ++s) {
        LD w1 = u(rng), w2 = u(rng);
        if (w1 + w2 > 1) { w1 = 1 - w1; w2 = 1 - w2; }
        // a + w1 (b - a) + w2 (c - a): exact on flat axes (differences are 0).
        LD p[3];
        for (int j = 0; j < 3; ++j) p[j] = LD(t[0][j]) + w1 * (LD(t[1][j]) - t[0][j]) + w2 * (LD(t[2][j]) - t[0][j]);
        if (!(p[axis] >= lo && p[axis] <= hi) || !in_ref(ref, p)) continue;
        EXPECT_TRUE(in_box(box, p));
        ++checked;
    }
    // 3. Never an inverted box; the axis bounds never leave the slab.
    if (!box.empty()) {
        EXPECT_GE(box.lo[axis], lo);
        EXPECT_LE(box.hi[axis], hi);
        for (int j = 0; j < 3; ++j) {
            EXPECT_GE(box.lo[j], ref.lo[j]);
            EXPECT_LE(box.hi[j], ref.hi[j]);
        }
    }
    return checked;
}

Aabb tri_box(const Tri& t) {
    Aabb b;
    for (const Vec3& v : t) b.grow(v);
    return b;
}

void random_case(std::mt19937_64& rng, float scale, float offset, bool flat, int& checked) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    Tri t;
    for (auto& v : t)
        for (float& c : v) c = offset + scale * u(rng);
    const int flat_axis = int(rng() % 3);
    if (flat)
        for (auto& v : t) v[flat_axis] = t[0][flat_axis];
    const int axis = int(rng() % 3);
    const Aabb tb = tri_box(t);
    std::uniform_real_distribution<float> f(0.0f, 1.0f);
    auto plane = [&] {
        switch (rng() % 4) {
            case 0: return t[rng() % 3][axis];  // exactly through a vertex
            default: return tb.lo[axis] + (tb.hi[axis] - tb.lo[axis]) * f(rng);
        }
    };
    float a = plane(), b = plane();
    if (a > b) std::swap(a, b);
    switch (rng() % 3) {
        case 0: a = -kInf; break;
        case 1: b = kInf; break;
        default: break;
    }
    // Reference box: the whole triangle box, or a random sub-box of it.
    Aabb ref = tb;
    if (rng() % 2) {
        for (int j = 0; j < 3; ++j) {
            float x = tb.lo[j] + (tb.hi[j] - tb.lo[j]) * f(rng), y = tb.lo[j] + (tb.hi[j] - tb.lo[j]) * f(rng);
            if (x > y) std::swap(x, y);
            ref.lo[j] = x;
            ref.hi[j] = y;
        }
    }
    checked += check(t, axis, a, b, ref, rng);
}

TEST(Clip, RandomTrianglesUnitScale) {
    std::mt19937_64 rng(1);
    int checked = 0;
    for (int i = 0; i < 20000; ++i) random_case(rng, 1.0f, 0.0f, false, checked);
    EXPECT_GT(checked, 100000);
}

TEST(Clip, FlatTriangles) {
    std::mt19937_64 rng(2);
    int checked = 0;
    for (int i = 0; i < 20000; ++i) random_case(rng, 1.0f, 0.0f, true, checked);
    EXPECT_GT(checked, 50000);
}

TEST(Clip, HugeTinyAndOffsetCoordinates) {
    std::mt19937_64 rng(3);
    int checked = 0;
    for (int i = 0; i < 10000; ++i) random_case(rng, 1e20f, 0.0f, false, checked);
    for (int i = 0; i < 10000; ++i) random_case(rng, 1e-20f, 0.0f, false, checked);
    for (int i = 0; i < 10000; ++i) random_case(rng, 1e-2f, 1e7f, false, checked);
    for (int i = 0; i < 10000; ++i) random_case(rng, 1e-2f, -1e7f, i % 2 == 0, checked);
    for (int i = 0; i < 10000; ++i) random_case(rng, 3e37f, 0.0f, false, checked);
    for (int i = 0; i < 10000; ++i) random_case(rng, 1e-38f, 0.0f, false, checked);  // subnormal results
    EXPECT_GT(checked, 100000);
}

TEST(Clip, TriangleInThePlane) {
    // Triangle lying in the plane x = 0.5: both sides get it, with zero width.
    const Tri t{{{0.5f, 0, 0}, {0.5f, 1, 0}, {0.5f, 0, 1}}};
    const Aabb l = clip_triangle(t, 0, -kInf, 0.5f, tri_box(t));
    const Aabb r = clip_triangle(t, 0, 0.5f, kInf, tri_box(t));
    ASSERT_FALSE(l.empty());
    ASSERT_FALSE(r.empty());
    EXPECT_EQ(l.lo[0], 0.5f);
    EXPECT_EQ(l.hi[0], 0.5f);
    EXPECT_EQ(r.hi[1], 1.0f);
}

TEST(Clip, MissingSideIsEmpty) {
    const Tri t{{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}};
    EXPECT_TRUE(clip_triangle(t, 0, 2.0f, 3.0f, tri_box(t)).empty());
    // The slab meets the triangle, but not inside the reference box.
    Aabb ref = tri_box(t);
    ref.lo[1] = 0.9f;  // only the tip near (0,1) remains: x <= 0.1
    EXPECT_TRUE(clip_triangle(t, 0, 0.5f, kInf, ref).empty());
    EXPECT_FALSE(clip_triangle(t, 0, -kInf, 0.5f, ref).empty());
}

TEST(Clip, DiagonalIsTighterThanBox) {
    // Chopping the triangle, not its box: the left part of a diagonal sliver
    // has a much smaller y-extent than the triangle's box.
    const Tri t{{{0, 0, 0}, {1, 1, 0}, {1, 1.01f, 0}}};
    const Aabb l = clip_triangle(t, 0, -kInf, 0.25f, tri_box(t));
    ASSERT_FALSE(l.empty());
    EXPECT_LT(l.hi[1], 0.26f);
    EXPECT_GE(l.hi[1], 0.2525f);  // (0.25, 0.2525) is on the edge to (1, 1.01)
}

TEST(Clip, ChopEqualsClipPerSlab) {
    // chop_triangle shares plane cuts between neighbouring slabs; it must be
    // bitwise equal to clipping each slab on its own.
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), f(0.0f, 1.0f);
    for (int i = 0; i < 5000; ++i) {
        Tri t;
        for (auto& p : t)
            for (float& c : p) c = u(rng);
        if (i % 4 == 0)
            for (auto& p : t) p[i % 3] = t[0][i % 3];  // flat
        const int axis = int(rng() % 3);
        const Aabb tb = tri_box(t);
        const int slabs = 1 + int(rng() % 12);
        std::vector<float> planes(slabs + 1);
        for (int s = 0; s <= slabs; ++s) {
            planes[s] = (rng() % 5 == 0) ? t[rng() % 3][axis]
                                         : tb.lo[axis] + (tb.hi[axis] - tb.lo[axis]) * f(rng);
        }
        std::sort(planes.begin(), planes.end());
        std::vector<Aabb> out(slabs);
        chop_triangle(t, axis, planes.data(), slabs, tb, out.data());
        for (int s = 0; s < slabs; ++s) {
            const Aabb one = clip_triangle(t, axis, planes[s], planes[s + 1], tb);
            ASSERT_EQ(std::memcmp(&one, &out[s], sizeof(Aabb)), 0) << i << " " << s;
        }
    }
}

/// chop_triangle_estimate as first written (3-coordinate loops; git 22a1014):
/// the rewrite must give the same float values (the SBVH's plane costs, and so
/// its trees, depend on them).
void chop_estimate_reference(const Tri& tri, int axis, const float* planes, int slabs, const Aabb& ref,
                             Aabb* out) {
    float emin[3], emax[3], inv[3];
    for (int e = 0; e < 3; ++e) {
        const Vec3& a = tri[e];
        const Vec3& b = tri[e == 2 ? 0 : e + 1];
        emin[e] = std::min(a[axis], b[axis]);
        emax[e] = std::max(a[axis], b[axis]);
        inv[e] = emax[e] > emin[e] ? 1.0f / (b[axis] - a[axis]) : 0.0f;
    }
    auto cut = [&](float c, Aabb& box) {
        for (int e = 0; e < 3; ++e) {
            if (!(emin[e] < c && c < emax[e])) continue;
            const Vec3& a = tri[e];
            const Vec3& b = tri[e == 2 ? 0 : e + 1];
            const float t = (c - a[axis]) * inv[e];
            for (int j = 0; j < 3; ++j) {
                const float v = j == axis ? c : a[j] + t * (b[j] - a[j]);
                box.lo[j] = std::min(box.lo[j], v);
                box.hi[j] = std::max(box.hi[j], v);
            }
        }
    };
    Aabb lower;
    cut(planes[0], lower);
    for (int s = 0; s < slabs; ++s) {
        const float lo = planes[s], hi = planes[s + 1];
        Aabb upper;
        cut(hi, upper);
        Aabb part = lower;
        for (int j = 0; j < 3; ++j) {
            part.lo[j] = std::min(part.lo[j], upper.lo[j]);
            part.hi[j] = std::max(part.hi[j], upper.hi[j]);
        }
        for (int k = 0; k < 3; ++k) {
            const float c = tri[k][axis];
            if (c >= lo && c <= hi) part.grow(tri[k]);
        }
        for (int j = 0; j < 3; ++j) {
            part.lo[j] = std::max(part.lo[j], ref.lo[j]);
            part.hi[j] = std::min(part.hi[j], ref.hi[j]);
        }
        part.lo[axis] = std::max(part.lo[axis], lo);
        part.hi[axis] = std::min(part.hi[axis], hi);
        out[s] = part.empty() ? Aabb{} : part;
        lower = upper;
    }
}

TEST(Clip, EstimateEqualsTheFirstImplementation) {
    // Same values (==: the sign of a zero may differ, which no cost sees), on
    // random, flat, axis-parallel and integer-grid triangles, planes through
    // vertices, repeated planes, planes beyond the triangle, small ref boxes.
    std::mt19937_64 rng(31);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), f(-0.2f, 1.2f);
    for (int i = 0; i < 20000; ++i) {
        Tri t;
        const int kind = i % 4;
        const float scale = std::ldexp(1.0f, int(rng() % 30) - 15);
        for (auto& p : t)
            for (float& c : p) c = kind == 3 ? float(int(rng() % 5) - 2) : u(rng) * scale;
        if (kind == 1) t[2] = t[0];                                // degenerate: two equal vertices
        if (kind == 2) t[1][int(rng() % 3)] = t[0][int(rng() % 3)];  // shared coordinates
        const int axis = int(rng() % 3);
        const Aabb tb = tri_box(t);
        const int slabs = 1 + int(rng() % 12);
        std::vector<float> planes(slabs + 1);
        for (int s = 0; s <= slabs; ++s) {
            planes[s] = (rng() % 4 == 0) ? t[rng() % 3][axis] : tb.lo[axis] + (tb.hi[axis] - tb.lo[axis]) * f(rng);
        }
        std::sort(planes.begin(), planes.end());
        Aabb ref = tb;
        if (i % 5 == 0) {
            for (int j = 0; j < 3; ++j) ref.hi[j] = ref.lo[j] + (ref.hi[j] - ref.lo[j]) * 0.7f;
        }
        std::vector<Aabb> want(slabs), got(slabs);
        chop_estimate_reference(t, axis, planes.data(), slabs, ref, want.data());
        chop_triangle_estimate(t, axis, planes.data(), slabs, ref, got.data());
        for (int s = 0; s < slabs; ++s) {
            ASSERT_EQ(got[s].empty(), want[s].empty()) << i << " " << s;
            if (want[s].empty()) continue;
            for (int j = 0; j < 3; ++j) {
                ASSERT_EQ(got[s].lo[j], want[s].lo[j]) << i << " " << s << " " << j;
                ASSERT_EQ(got[s].hi[j], want[s].hi[j]) << i << " " << s << " " << j;
            }
        }
    }
}

TEST(Clip, EstimateIsCloseToConservativeChop) {
    // chop_triangle_estimate (plain float, used only for the SBVH's plane
    // costs) may differ from the conservative chop by rounding, nothing more:
    // every bound within a few ulps of the coordinate scale, and a slab the
    // conservative chop finds empty is empty or degenerate-thin here.
    std::mt19937_64 rng(12);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f), f(0.0f, 1.0f);
    for (int i = 0; i < 5000; ++i) {
        Tri t;
        const float scale = std::ldexp(1.0f, int(rng() % 40) - 20);
        for (auto& p : t)
            for (float& c : p) c = u(rng) * scale;
        const int axis = int(rng() % 3);
        const Aabb tb = tri_box(t);
        const int slabs = 1 + int(rng() % 12);
        std::vector<float> planes(slabs + 1);
        for (int s = 0; s <= slabs; ++s) planes[s] = tb.lo[axis] + (tb.hi[axis] - tb.lo[axis]) * f(rng);
        std::sort(planes.begin(), planes.end());
        std::vector<Aabb> exact(slabs), est(slabs);
        chop_triangle(t, axis, planes.data(), slabs, tb, exact.data());
        chop_triangle_estimate(t, axis, planes.data(), slabs, tb, est.data());
        const float tol = 8.0f * std::numeric_limits<float>::epsilon() * 2.0f * scale;
        for (int s = 0; s < slabs; ++s) {
            if (exact[s].empty()) {
                if (!est[s].empty()) {
                    EXPECT_LE(est[s].half_area(), double(tol) * 4.0 * scale) << i;
                }
                continue;
            }
            if (est[s].empty()) {
                EXPECT_LE(exact[s].half_area(), double(tol) * 4.0 * scale) << i << " " << s;
                continue;
            }
            for (int j = 0; j < 3; ++j) {
                EXPECT_NEAR(est[s].lo[j], exact[s].lo[j], tol) << i << " " << s << " " << j;
                EXPECT_NEAR(est[s].hi[j], exact[s].hi[j], tol) << i << " " << s << " " << j;
            }
        }
    }
}

}  // namespace
}  // namespace cwbvh::compiler
