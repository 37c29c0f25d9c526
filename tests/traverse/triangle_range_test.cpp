// The watertight test's float range stage (watertight_range_miss, triangle_intersect.h):
// it may only reject a triangle whose exact plane distance T lies outside [tmin, tmax].
// T is computed here in binary128 from the same float inputs (differences of floats
// within 2^80 of each other are exact there; products and sums err by 2^-113 relative,
// far below the stage's 2^-20 margin), and tmin/tmax are placed at every distance from
// T the stage could misjudge: T (1 +- k u) for k from 1/2 to 2^20, rounded both ways.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <random>

#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh::test {
namespace {

using q128 = __float128;

struct ExactT {
    bool defined = false;  ///< DEN != 0
    q128 t = 0;
};

/// T = ((v1 - v0) x (v2 - v0)) . (v0 - o) / ((v1 - v0) x (v2 - v0)) . d in binary128.
ExactT exact_t(const Ray& r, const float* v0, const float* v1, const float* v2) {
    q128 e1[3], e2[3], a[3];
    for (int i = 0; i < 3; ++i) {
        e1[i] = q128(v1[i]) - q128(v0[i]);
        e2[i] = q128(v2[i]) - q128(v0[i]);
        a[i] = q128(v0[i]) - q128(r.org[i]);
    }
    const q128 n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const q128 num = n[0] * a[0] + n[1] * a[1] + n[2] * a[2];
    const q128 den = n[0] * q128(r.dir[0]) + n[1] * q128(r.dir[1]) + n[2] * q128(r.dir[2]);
    ExactT out;
    if (den == 0) return out;
    out.defined = true;
    out.t = num / den;
    return out;
}

float next_up(float x) { return std::nextafter(x, INFINITY); }
float next_down(float x) { return std::nextafter(x, -INFINITY); }

struct Tally {
    uint64_t cases = 0;     ///< (triangle, range) pairs tried
    uint64_t rejected = 0;  ///< the stage said "outside"
    uint64_t wrong = 0;     ///< ... while the exact T lies inside [tmin, tmax]
    uint64_t far_decided = 0;  ///< rejected with tmax <= T (1 - 1024u): the stage's reach
    uint64_t far_cases = 0;
    uint64_t conflicts = 0;  ///< the stage rejected, the whole test (double path) accepted
    // watertight_range_interval (the deferred hits of cwbvh_lane.h):
    uint64_t interval_verdict_differs = 0;  ///< its kMiss differs from watertight_range_miss
    uint64_t interval_inside = 0;           ///< kInside with agreeing, nonzero edge signs
    uint64_t interval_wrong = 0;            ///< ... where the whole test missed or its t left [lo, hi]
    uint64_t tlo_inside = 0;                ///< kInside with a tlo below tmax
};

/// watertight_range_interval on the same range: its kMiss is watertight_range_miss's
/// answer, and where it says kInside (and the edge signs agree, all nonzero: what
/// test_triangle_deferred also requires) the whole test, with tmax = hi and with the
/// range's own tmax, hits at a t in [lo, hi], tmin <= lo and hi <= tmax, and
/// watertight_finish gives that hit's t, u, v bit for bit.
void check_interval(const WatertightRay& w, const float* v0, const float* v1, const float* v2, float tmin,
                    float tmax, bool miss, Tally& tally) {
    float lo = NAN, hi = NAN;
    // A lower bound tlo of a deferred closest hit below tmax: kInside needs hi <= tlo, and
    // tlo changes nothing else (kMiss is the stage's answer for [tmin, tmax]).
    if (std::isfinite(tmax) && tmax > 0.0f) {
        for (const float tlo : {next_down(tmax), tmax * 0.99951171875f, tmax * 0.5f}) {
            float l2 = NAN, h2 = NAN;
            const RangeVerdict vt = watertight_range_interval(w, v0, v1, v2, tmin, tlo, tmax, l2, h2);
            if ((vt == RangeVerdict::kMiss) != miss) ++tally.interval_verdict_differs;
            tally.tlo_inside += vt == RangeVerdict::kInside;
            if (vt == RangeVerdict::kInside && !(h2 <= tlo && l2 >= tmin)) ++tally.interval_wrong;
        }
    }
    const RangeVerdict v = watertight_range_interval(w, v0, v1, v2, tmin, tmax, tmax, lo, hi);
    if ((v == RangeVerdict::kMiss) != miss) ++tally.interval_verdict_differs;
    WatertightEdges e;
    if (v != RangeVerdict::kInside || !watertight_edges(w, v0, v1, v2, e) || !is_finite_nonzero_f(e.eu) ||
        !is_finite_nonzero_f(e.ev) || !is_finite_nonzero_f(e.ew))
        return;
    ++tally.interval_inside;
    TriangleHit a{}, b{};
    const bool ha = intersect_triangle_watertight(w, v0, v1, v2, tmin, hi, a);
    const bool hb = intersect_triangle_watertight(w, v0, v1, v2, tmin, tmax, b);
    // A deferred hit is finished by watertight_finish: the whole test's t, u, v bit for bit.
    const TriangleHit f = watertight_finish(w, v0, v1, v2);
    const bool same = std::memcmp(&f, &a, sizeof f) == 0 && std::memcmp(&a, &b, sizeof a) == 0;
    if (!(ha && hb && same && lo <= a.t && a.t <= hi && tmin <= lo && hi <= tmax && lo < hi)) {
        if (++tally.interval_wrong <= 5)
            std::printf("interval wrong: lo %.9g hi %.9g hit %d t %.9g, tmin %.9g tmax %.9g\n", double(lo), double(hi),
                        int(ha), double(a.t), double(tmin), double(tmax));
    }
}

/// Every range around T the stage could misjudge, both ends.
void check_ranges(const Ray& ray, const float* v0, const float* v1, const float* v2, Tally& tally) {
    const ExactT ex = exact_t(ray, v0, v1, v2);
    if (!ex.defined) return;
    const double T = double(ex.t);
    if (!std::isfinite(T) || std::fabs(T) > 1e37 || std::fabs(T) < 1e-37) return;
    const WatertightRay w = make_watertight_ray(ray);
    const double u = std::ldexp(1.0, -24);
    for (int e = -1; e <= 20; ++e) {
        const double k = std::ldexp(1.0, e);
        for (int side = -1; side <= 1; side += 2) {
            const double edge = T * (1.0 + side * k * u);
            const float lo = float(edge), cands[3] = {lo, next_up(lo), next_down(lo)};
            for (float end : cands) {
                if (!std::isfinite(end)) continue;
                // end as tmax (tmin 0 when T > 0) and as tmin (tmax +inf).
                const float ranges[2][2] = {{T > 0 ? 0.0f : -INFINITY, end}, {end, INFINITY}};
                for (const auto& rg : ranges) {
                    const float tmin = rg[0], tmax = rg[1];
                    if (!(tmin <= tmax)) continue;
                    ++tally.cases;
                    const bool miss = watertight_range_miss(w, v0, v1, v2, tmin, tmax);
                    const bool inside = q128(tmin) <= ex.t && ex.t <= q128(tmax);
                    if (miss) ++tally.rejected;
                    // The GPU runs the stage, the host does not (its fmas are libm calls
                    // there): both must decide alike, so whatever the stage rejects the
                    // host's whole test (stage skipped, double distance) rejects too.
                    TriangleHit th;
                    if (miss && intersect_triangle_watertight(w, v0, v1, v2, tmin, tmax, th)) ++tally.conflicts;
                    check_interval(w, v0, v1, v2, tmin, tmax, miss, tally);
                    if (miss && inside) {
                        if (++tally.wrong <= 5)
                            std::printf("wrong reject: T %.17g tmin %.9g tmax %.9g\n", T, double(tmin), double(tmax));
                    }
                    if (T > 0 && tmin == 0.0f && e >= 10 && side < 0) {
                        ++tally.far_cases;
                        tally.far_decided += miss;
                    }
                }
            }
        }
    }
}

float random_coord(std::mt19937& rng, int emin, int emax) {
    std::uniform_real_distribution<float> m(1.0f, 2.0f);
    std::uniform_int_distribution<int> e(emin, emax), s(0, 1);
    return (s(rng) ? -1.0f : 1.0f) * std::ldexp(m(rng), e(rng));
}

TEST(TriangleRange, RejectsOnlyWhatLiesOutsideTheRange) {
    std::mt19937 rng(20261126);
    Tally tally;
    for (int scale : {-40, -20, 0, 20, 40}) {
        for (int i = 0; i < 3000; ++i) {
            float v[3][3];
            Ray ray{};
            // A triangle of size 2^scale around a point up to 2^(scale + 8) away, ray
            // from a point near the origin towards a random point of the triangle.
            const float c[3] = {random_coord(rng, scale, scale + 8), random_coord(rng, scale, scale + 8),
                                random_coord(rng, scale, scale + 8)};
            for (auto& vert : v)
                for (int a = 0; a < 3; ++a) vert[a] = c[a] + random_coord(rng, scale - 4, scale);
            std::uniform_real_distribution<float> bary(0.0f, 1.0f);
            const float b1 = bary(rng), b2 = bary(rng) * (1 - b1);
            for (int a = 0; a < 3; ++a) {
                ray.org[a] = random_coord(rng, scale - 2, scale + 2);
                const float target = v[0][a] + b1 * (v[1][a] - v[0][a]) + b2 * (v[2][a] - v[0][a]);
                ray.dir[a] = target - ray.org[a];
            }
            if (ray.dir[0] == 0 && ray.dir[1] == 0 && ray.dir[2] == 0) continue;
            ray.tmin = 0;
            ray.tmax = INFINITY;
            check_ranges(ray, v[0], v[1], v[2], tally);
        }
    }
    std::printf("cases %llu rejected %llu wrong %llu; tmax below T by >= 1024u: %llu of %llu rejected\n",
                (unsigned long long)tally.cases, (unsigned long long)tally.rejected, (unsigned long long)tally.wrong,
                (unsigned long long)tally.far_decided, (unsigned long long)tally.far_cases);
    EXPECT_EQ(tally.wrong, 0u);
    EXPECT_EQ(tally.conflicts, 0u);
    std::printf("interval: kInside %llu (%llu with tlo < tmax), wrong %llu, kMiss differing from the stage %llu\n",
                (unsigned long long)tally.interval_inside, (unsigned long long)tally.tlo_inside,
                (unsigned long long)tally.interval_wrong, (unsigned long long)tally.interval_verdict_differs);
    EXPECT_EQ(tally.interval_wrong, 0u);
    EXPECT_EQ(tally.interval_verdict_differs, 0u);
    EXPECT_GT(tally.tlo_inside, 0u);
    // Deferring must be worth it: most ranges that hold T with room to spare are decided.
    EXPECT_GT(tally.interval_inside, tally.cases / 20);
    // The stage must be worth its instructions: it decides most ranges that end well
    // before T (a hit behind the closest one), not only the obvious ones.
    EXPECT_GT(tally.far_decided, tally.far_cases * 85 / 100);
}

TEST(TriangleRange, SliversGrazingRaysAndHugeOrTinyCoordinates) {
    std::mt19937 rng(7);
    Tally tally;
    for (int i = 0; i < 4000; ++i) {
        Ray ray{};
        float v[3][3];
        const int kind = i % 4;
        const int scale = kind == 2 ? 120 : (kind == 3 ? -120 : 0);
        for (int a = 0; a < 3; ++a) {
            v[0][a] = random_coord(rng, scale - 2, scale);
            v[1][a] = v[0][a] + random_coord(rng, scale - 3, scale - 1);
            // Slivers: the third vertex almost on the first edge.
            v[2][a] = kind == 0 ? v[0][a] + 0.5f * (v[1][a] - v[0][a]) * (1.0f + random_coord(rng, -22, -18))
                                : v[0][a] + random_coord(rng, scale - 3, scale - 1);
            ray.org[a] = random_coord(rng, scale - 1, scale + 1);
        }
        for (int a = 0; a < 3; ++a) ray.dir[a] = v[0][a] - ray.org[a];
        if (kind == 1) ray.dir[2] = ray.dir[2] * 1e-6f + random_coord(rng, -30, -20);  // grazing
        ray.tmin = 0;
        ray.tmax = INFINITY;
        check_ranges(ray, v[0], v[1], v[2], tally);
    }
    std::printf("cases %llu rejected %llu wrong %llu\n", (unsigned long long)tally.cases,
                (unsigned long long)tally.rejected, (unsigned long long)tally.wrong);
    EXPECT_EQ(tally.wrong, 0u);
    EXPECT_EQ(tally.conflicts, 0u);
    EXPECT_GT(tally.rejected, 0u);
    std::printf("interval: kInside %llu, wrong %llu, kMiss differing from the stage %llu\n",
                (unsigned long long)tally.interval_inside, (unsigned long long)tally.interval_wrong,
                (unsigned long long)tally.interval_verdict_differs);
    EXPECT_EQ(tally.interval_wrong, 0u);
    EXPECT_EQ(tally.interval_verdict_differs, 0u);
}

TEST(TriangleRange, UndecidableInputsAreLeftToTheDoublePath) {
    const float v0[3] = {0, 0, 1}, v1[3] = {1, 0, 1}, v2[3] = {0, 1, 1};
    Ray r{};
    r.org[0] = 0.25f;
    r.org[1] = 0.25f;
    r.dir[2] = 1.0f;
    const WatertightRay w = make_watertight_ray(r);
    // T = 1: inside, at either end, and an infinite or NaN end never rejects.
    EXPECT_FALSE(watertight_range_miss(w, v0, v1, v2, 0.0f, INFINITY));
    EXPECT_FALSE(watertight_range_miss(w, v0, v1, v2, 1.0f, 1.0f));
    EXPECT_FALSE(watertight_range_miss(w, v0, v1, v2, -INFINITY, 1.0f));
    EXPECT_FALSE(watertight_range_miss(w, v0, v1, v2, 0.0f, NAN));
    EXPECT_FALSE(watertight_range_miss(w, v0, v1, v2, NAN, 2.0f));
    // Clearly outside: rejected.
    EXPECT_TRUE(watertight_range_miss(w, v0, v1, v2, 0.0f, 0.5f));
    EXPECT_TRUE(watertight_range_miss(w, v0, v1, v2, 1.5f, INFINITY));
    // A ray in the triangle's plane (DEN = 0) and a degenerate triangle: undecided.
    Ray p{};
    p.org[2] = 1.0f;
    p.dir[0] = 1.0f;
    EXPECT_FALSE(watertight_range_miss(make_watertight_ray(p), v0, v1, v2, 0.0f, 0.5f));
    const float d2[3] = {2, 0, 1};
    EXPECT_FALSE(watertight_range_miss(w, v0, v1, d2, 0.0f, 0.5f));
    // Coordinates whose products overflow: undecided, never a wrong reject.
    const float h0[3] = {-3e38f, -3e38f, 1e38f}, h1[3] = {3e38f, -3e38f, 1e38f}, h2[3] = {-3e38f, 3e38f, 1e38f};
    EXPECT_FALSE(watertight_range_miss(w, h0, h1, h2, 0.0f, 0.5f));
}

}  // namespace
}  // namespace cwbvh::test
