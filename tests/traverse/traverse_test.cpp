// CWBVH and BVH2 traversal against the exact oracle; watertightness on closed and
// shared-edge meshes; defined answers for degenerate rays; extreme scales.
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/traverse_bvh2.h"
#include "cwbvh/oracle/oracle.h"
#include "traverse/test_scenes.h"

namespace cwbvh::test {
namespace {

struct Scene {
    std::vector<TriangleRecord> input;
    WideBvh wide;
    Bvh2 bvh2;
    explicit Scene(std::vector<TriangleRecord> t) : input(std::move(t)), wide(build_wide(input)), bvh2(build_bvh2(input)) {}
    template <TriangleTest kTest, HitMode kMode>
    TraceStatus trace(const Ray& r, Hit& h, TraceCounters* c = nullptr) const {
        LocalStack<kCpuStackSize> stack;
        return traverse_cwbvh<kTest, kMode>(wide.nodes.data(), uint32_t(wide.nodes.size()), wide.tris.data(),
                                            uint32_t(wide.tris.size()), r, h, stack, c);
    }
    template <TriangleTest kTest, HitMode kMode>
    TraceStatus trace2(const Ray& r, Hit& h, TraceCounters* c = nullptr) const {
        return traverse_bvh2<kTest, kMode>(bvh2.nodes.data(), uint32_t(bvh2.nodes.size()), input.data(),
                                           uint32_t(input.size()), r, h, c);
    }
};

std::vector<Ray> random_rays(size_t n, float lo, float hi, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> p(lo, hi), d(-1, 1);
    std::vector<Ray> rays(n);
    for (auto& r : rays) {
        for (int a = 0; a < 3; ++a) {
            r.org[a] = p(rng);
            r.dir[a] = d(rng);
        }
        if (rng() % 8 == 0) r.dir[rng() % 3] = (rng() & 1) ? 0.0f : -0.0f;  // axis-parallel-ish
        r.tmin = 0.0f;
        r.tmax = INFINITY;
    }
    return rays;
}

// Rays with an exact hit within the oracle's tolerance of tmin or tmax ("near an end": the
// traversal may take or leave that hit) get the weaker check of compare_near_end instead of
// the exact one; each test bounds their fraction (max_near_end), so that a change that
// makes most rays ambiguous cannot pass by checking few.
struct Agreement {
    uint64_t rays = 0, skipped = 0, hit_mismatch = 0, prim_mismatch = 0, t_mismatch = 0, near_end_errors = 0;
    uint64_t errors() const { return hit_mismatch + prim_mismatch + t_mismatch + near_end_errors; }
    double skipped_fraction() const { return rays == 0 ? 0.0 : double(skipped) / double(rays); }
};

/// What a near-end answer must still be: a reported hit is a real hit of that triangle at
/// its t (within tol), inside the range (within tol), and not behind the closest hit that
/// is clearly inside; a miss only when no hit is clearly inside the range.
void compare_near_end(const Ray& r, const std::vector<TriangleRecord>& tris, const OracleResult& o, const Hit& h,
                      Agreement& a) {
    ++a.skipped;
    const long double tol = o.tol, tmin = r.tmin, tmax = r.tmax;
    const bool inside = o.hit && o.t > tmin + tol && o.t < tmax - tol;
    if (h.prim == kMissPrim) {
        a.near_end_errors += inside;
        return;
    }
    long double t;
    const bool real = oracle_hits_prim(r, tris.data(), tris.size(), h.prim, t) &&
                      std::fabs((long double)h.t - t) <= tol && t >= tmin - tol && t <= tmax + tol;
    a.near_end_errors += !real || (inside && t > o.t + tol);
}

void compare(const Ray& r, const std::vector<TriangleRecord>& tris, const OracleResult& o, const Hit& h,
             Agreement& a) {
    ++a.rays;
    if (o.near_range_end) {
        compare_near_end(r, tris, o, h, a);
        return;
    }
    const bool hit = h.prim != kMissPrim;
    if (hit != o.hit) {
        ++a.hit_mismatch;
        return;
    }
    if (!hit) return;
    if (std::find(o.ties.begin(), o.ties.end(), h.prim) == o.ties.end()) ++a.prim_mismatch;
    else if (std::fabs((long double)h.t - o.t) > o.tol) ++a.t_mismatch;
}

template <TriangleTest kTest>
Agreement closest_vs_oracle(const Scene& s, const std::vector<Ray>& rays, bool bvh2) {
    Agreement a;
    for (const Ray& r : rays) {
        Hit h;
        const TraceStatus st = bvh2 ? s.trace2<kTest, HitMode::kClosest>(r, h) : s.trace<kTest, HitMode::kClosest>(r, h);
        EXPECT_EQ(st, TraceStatus::kOk);
        compare(r, s.input, oracle_trace(r, s.input.data(), s.input.size()), h, a);
    }
    return a;
}

void print(const char* what, const Agreement& a) {
    std::printf("%-44s rays %6llu  near an end %llu (%.1f%%, %llu wrong)  hit/miss %llu  prim %llu  t %llu\n", what,
                (unsigned long long)a.rays, (unsigned long long)a.skipped, 100.0 * a.skipped_fraction(),
                (unsigned long long)a.near_end_errors, (unsigned long long)a.hit_mismatch,
                (unsigned long long)a.prim_mismatch, (unsigned long long)a.t_mismatch);
}

/// At most `max_near_end` of the rays may have had only the near-end check.
void expect_near_end_at_most(const Agreement& a, double max_near_end, const std::string& what) {
    EXPECT_GT(a.rays, 0u) << what;
    EXPECT_LE(a.skipped_fraction(), max_near_end)
        << what << ": " << a.skipped << " of " << a.rays << " rays near a range end (only the weak check)";
}

TEST(Traverse, BuilderMakesValidTree) {
    const Scene s(random_soup(3000, 100, 2, 7));
    EXPECT_EQ(s.wide.tris.size(), s.input.size());
    EXPECT_LE(s.wide.depth, 64);
    // Every decoded child box contains its subtree: checked indirectly by every
    // test below; here the structural rules the traversal relies on.
    for (const CwbvhNode& n : s.wide.nodes) {
        int tris = 0;
        for (int k = 0; k < 8; ++k) {
            EXPECT_EQ(meta_is_internal(n.meta[k]), bool((n.imask >> k) & 1));
            if (meta_is_leaf(n.meta[k])) tris += meta_leaf_count(n.meta[k]);
        }
        EXPECT_LE(tris, 24);
    }
}

TEST(Traverse, ClosestHitMatchesOracle) {
    const Scene s(random_soup(2000, 100, 4, 1));
    const auto rays = random_rays(4000, -20, 120, 2);
    const Agreement ww = closest_vs_oracle<TriangleTest::kWatertight>(s, rays, false);
    const Agreement wf = closest_vs_oracle<TriangleTest::kFast>(s, rays, false);
    const Agreement bw = closest_vs_oracle<TriangleTest::kWatertight>(s, rays, true);
    print("CWBVH watertight vs oracle (soup)", ww);
    print("CWBVH fast vs oracle (soup)", wf);
    print("BVH2 watertight vs oracle (soup)", bw);
    EXPECT_EQ(ww.errors(), 0u);
    EXPECT_EQ(bw.errors(), 0u);
    EXPECT_LE(wf.errors(), rays.size() / 1000);
    for (const Agreement* a : {&ww, &wf, &bw}) expect_near_end_at_most(*a, 0.01, "soup");
}

TEST(Traverse, AnyHitReturnsRealHit) {
    const Scene s(random_soup(2000, 100, 4, 3));
    const auto rays = random_rays(4000, -20, 120, 4);
    uint64_t oracle_hits = 0, missed = 0, fake = 0, near_end = 0;
    for (const Ray& r : rays) {
        const OracleResult o = oracle_trace(r, s.input.data(), s.input.size());
        Hit h;
        EXPECT_EQ((s.trace<TriangleTest::kWatertight, HitMode::kAny>(r, h)), TraceStatus::kOk);
        if (o.near_range_end) {  // the hit near the end may count or not: not checked, but bounded
            ++near_end;
            continue;
        }
        oracle_hits += o.hit;
        if (o.hit && h.prim == kMissPrim) ++missed;
        if (h.prim != kMissPrim) {
            long double t;
            if (!oracle_hits_prim(r, s.input.data(), s.input.size(), h.prim, t) || t < r.tmin - o.tol ||
                std::fabs((long double)h.t - t) > o.tol)
                ++fake;
        }
    }
    std::printf("any-hit: %llu oracle hits, %llu missed, %llu not real\n", (unsigned long long)oracle_hits,
                (unsigned long long)missed, (unsigned long long)fake);
    std::printf("any-hit: %llu of %llu rays near a range end, unchecked\n", (unsigned long long)near_end,
                (unsigned long long)rays.size());
    EXPECT_GT(oracle_hits, 100u);
    EXPECT_EQ(missed, 0u);
    EXPECT_EQ(fake, 0u);
    EXPECT_LE(near_end, rays.size() / 100);
}

// Rays aimed exactly at vertices and edge midpoints of a 64 x 64 bumpy grid (integer
// and half-integer coordinates, exact), from 7^3 - 7^2 directions, at scales 2^k.
struct LeakCount {
    uint64_t rays = 0, watertight_miss = 0, fast_miss = 0, bvh2_miss = 0;
};

LeakCount grid_leaks(double scale, double offset) {
    Mesh m = grid_mesh(64);
    m.transform(scale, offset);
    const Scene s(m.tris());
    LeakCount c;
    std::mt19937 rng(9);
    for (int rep = 0; rep < 6000; ++rep) {
        const int i = 8 + int(rng() % 48), j = 8 + int(rng() % 48);
        const int kind = int(rng() % 4);
        const int i2 = kind == 1 || kind == 3 ? i + 1 : i, j2 = kind == 2 || kind == 3 ? j + 1 : j;
        const float* va = &m.v[(j * 65 + i) * 3];
        const float* vb = &m.v[(j2 * 65 + i2) * 3];
        float x[3];
        for (int a = 0; a < 3; ++a) x[a] = float((double(va[a]) + vb[a]) * 0.5);  // exact when scale is 2^k
        float d[3] = {float(int(rng() % 7) - 3), float(int(rng() % 7) - 3), float(int(rng() % 3) + 1)};
        if (rng() & 1) d[2] = -d[2];
        float o[3];
        for (int a = 0; a < 3; ++a) o[a] = float(double(x[a]) - 4.0 * scale * d[a]);
        const Ray r = make_ray(o, d);
        Hit h;
        ++c.rays;
        s.trace<TriangleTest::kWatertight, HitMode::kClosest>(r, h);
        c.watertight_miss += h.prim == kMissPrim;
        s.trace<TriangleTest::kFast, HitMode::kClosest>(r, h);
        c.fast_miss += h.prim == kMissPrim;
        s.trace2<TriangleTest::kWatertight, HitMode::kAny>(r, h);
        c.bvh2_miss += h.prim == kMissPrim;
    }
    return c;
}

TEST(Watertight, GridEdgesAndVertices) {
    for (int k : {0, -66, -20, 20, 66}) {
        const LeakCount c = grid_leaks(std::ldexp(1.0, k), 0.0);
        std::printf("grid 64x64 scale 2^%d: %llu rays at edges/vertices; misses: watertight %llu, fast %llu, bvh2 %llu\n",
                    k, (unsigned long long)c.rays, (unsigned long long)c.watertight_miss,
                    (unsigned long long)c.fast_miss, (unsigned long long)c.bvh2_miss);
        EXPECT_EQ(c.watertight_miss, 0u) << "scale 2^" << k;
        EXPECT_EQ(c.bvh2_miss, 0u) << "scale 2^" << k;
    }
    for (double sc : {1e-20, 1e20, 0.1}) {
        const LeakCount c = grid_leaks(sc, 0.0);  // rounded vertices (still shared), rays near edges
        std::printf("grid 64x64 scale %g: misses: watertight %llu, fast %llu, bvh2 %llu of %llu\n", sc,
                    (unsigned long long)c.watertight_miss, (unsigned long long)c.fast_miss,
                    (unsigned long long)c.bvh2_miss, (unsigned long long)c.rays);
        EXPECT_EQ(c.watertight_miss, 0u) << "scale " << sc;
    }
}

// From inside a closed mesh every ray must hit. Targets: vertices and edge midpoints.
LeakCount closed_leaks(const Mesh& m, const float* center, float jitter, uint32_t seed, int count) {
    const Scene s(m.tris());
    LeakCount c;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> jit(-jitter, jitter);
    for (int rep = 0; rep < count; ++rep) {
        const size_t t = rng() % (m.idx.size() / 3);
        const int e = int(rng() % 3);
        const float* va = &m.v[m.idx[t * 3 + e] * 3];
        const float* vb = &m.v[m.idx[t * 3 + (e + 1) % 3] * 3];
        const bool vertex = rng() & 1;
        float x[3], o[3], d[3];
        for (int a = 0; a < 3; ++a) {
            x[a] = vertex ? va[a] : float(0.5 * (double(va[a]) + vb[a]));
            o[a] = center[a] + (jitter > 0 ? std::round(jit(rng) * 4) / 4 : 0.0f);
            d[a] = x[a] - o[a];
        }
        const Ray r = make_ray(o, d);
        if (!ray_is_traceable(r)) continue;
        Hit h;
        ++c.rays;
        s.trace<TriangleTest::kWatertight, HitMode::kClosest>(r, h);
        c.watertight_miss += h.prim == kMissPrim;
        s.trace<TriangleTest::kFast, HitMode::kClosest>(r, h);
        c.fast_miss += h.prim == kMissPrim;
        s.trace2<TriangleTest::kWatertight, HitMode::kClosest>(r, h);
        c.bvh2_miss += h.prim == kMissPrim;
    }
    return c;
}

TEST(Watertight, ClosedCubeAndSphere) {
    struct Case {
        const char* name;
        bool sphere;
        double scale, offset;
    };
    for (const Case& cs : {Case{"cube", false, 1, 0}, Case{"cube 2^-60", false, std::ldexp(1.0, -60), 0},
                           Case{"cube 2^60", false, std::ldexp(1.0, 60), 0}, Case{"cube +1e7", false, 1, 1e7},
                           Case{"sphere", true, 1, 0}, Case{"sphere 1e-20", true, 1e-20, 0},
                           Case{"sphere 1e20", true, 1e20, 0}, Case{"sphere 0.01 +1e7", true, 0.01 * 1024, 1e7}}) {
        Mesh m = cube_mesh(32, cs.sphere);
        m.transform(cs.scale, cs.offset);
        const float c = float(16.0 * cs.scale + cs.offset);
        const float center[3] = {c, c, c};
        const LeakCount l = closed_leaks(m, center, cs.scale == 1 && cs.offset == 0 ? 8.0f : 0.0f, 5, 20000);
        std::printf("closed %-18s %llu rays from inside; misses: watertight %llu, fast %llu, bvh2 %llu\n", cs.name,
                    (unsigned long long)l.rays, (unsigned long long)l.watertight_miss,
                    (unsigned long long)l.fast_miss, (unsigned long long)l.bvh2_miss);
        EXPECT_EQ(l.watertight_miss, 0u) << cs.name;
        EXPECT_EQ(l.bvh2_miss, 0u) << cs.name;
    }
}

TEST(Traverse, DefinedAnswersForDegenerateRays) {
    const Scene s(random_soup(500, 10, 2, 11));
    const float nan = NAN, inf = INFINITY;
    const std::vector<Ray> bad = {
        {{nan, 0, 0}, 0, {1, 0, 0}, inf}, {{0, 0, 0}, 0, {nan, 1, 0}, inf}, {{0, 0, 0}, nan, {1, 1, 1}, inf},
        {{0, 0, 0}, 0, {1, 1, 1}, nan},   {{inf, 0, 0}, 0, {1, 0, 0}, inf}, {{0, 0, 0}, 0, {0, -inf, 0}, inf},
        {{0, 0, 0}, 0, {0, -0.0f, 0}, inf}, {{0, 0, 0}, 5, {1, 1, 1}, 4},
    };
    for (const Ray& r : bad) {
        Hit h;
        EXPECT_EQ((s.trace<TriangleTest::kWatertight, HitMode::kClosest>(r, h)), TraceStatus::kInvalidRay);
        EXPECT_EQ(h.prim, kMissPrim);
        EXPECT_EQ((s.trace2<TriangleTest::kFast, HitMode::kAny>(r, h)), TraceStatus::kInvalidRay);
        EXPECT_EQ(h.prim, kMissPrim);
    }
    // Valid corner cases: tmax = 0, tmin = tmax, infinite tmin, huge and tiny directions.
    const std::vector<Ray> ok = {
        {{5, 5, -5}, 0, {0, 0, 1}, 0},     {{5, 5, -5}, 3, {0, 0, 1}, 3},
        {{5, 5, -5}, -inf, {0, 0, 1}, inf}, {{5, 5, -5}, 0, {1e-30f, 1e-38f, 1e38f}, inf},
        {{5, 5, -5}, 0, {1e-45f, 0, 1e-45f}, inf}, {{5, 5, 5}, 0, {3e38f, -3e38f, 3e38f}, inf},
    };
    for (const Ray& r : ok) {
        Hit h;
        EXPECT_EQ((s.trace<TriangleTest::kWatertight, HitMode::kClosest>(r, h)), TraceStatus::kOk);
        const OracleResult o = oracle_trace(r, s.input.data(), s.input.size());
        if (!o.near_range_end) {
            EXPECT_EQ(h.prim != kMissPrim, o.hit) << r.dir[0] << " " << r.tmin << " " << r.tmax;
        }
    }
}

TEST(Traverse, ExtremeScalesAndOffsetAgreeWithOracle) {
    struct Case {
        const char* name;
        double scale, offset, size;
        double max_near_end;  ///< fraction of rays near a range end (measured + margin)
    };
    // Measured near-end fractions (2026-11-26): 0 in the first three cases, 393 of 1500
    // (26.2%) in the last, where a float step is 1 and the oracle's tolerance (2^-18 of
    // |org| + extent) about 40 units of t, so every ray whose first hit is that close to its
    // origin is near tmin. Those rays get compare_near_end's check (0 wrong), not none.
    for (const Case& cs : {Case{"scale 1e-20", 1e-20, 0, 2, 0.01}, Case{"scale 1e20", 1e20, 0, 2, 0.01},
                           Case{"offset 1e7, 1e-2 detail", 1e-3, 1e7, 1e-2 / 1e-3, 0.01},
                           Case{"offset 1e7, 1 detail", 1.0, 1e7, 4, 0.30}}) {
        auto soup = random_soup(1500, 100, float(cs.size), 21);
        for (auto& t : soup)
            for (float* v : {t.v0, t.v1, t.v2})
                for (int a = 0; a < 3; ++a) v[a] = float(double(v[a]) * cs.scale + cs.offset);
        const Scene s(soup);
        auto rays = random_rays(1500, -20, 120, 22);
        for (auto& r : rays)
            for (int a = 0; a < 3; ++a) r.org[a] = float(double(r.org[a]) * cs.scale + cs.offset);
        const Agreement w = closest_vs_oracle<TriangleTest::kWatertight>(s, rays, false);
        const Agreement f = closest_vs_oracle<TriangleTest::kFast>(s, rays, false);
        char buf[128];
        std::snprintf(buf, sizeof buf, "CWBVH watertight, %s", cs.name);
        print(buf, w);
        std::snprintf(buf, sizeof buf, "CWBVH fast, %s", cs.name);
        print(buf, f);
        EXPECT_LE(w.errors(), rays.size() / 500) << cs.name;
        expect_near_end_at_most(w, cs.max_near_end, cs.name);
        expect_near_end_at_most(f, cs.max_near_end, cs.name);
    }
}

TEST(Traverse, CpuTraceThreadsAndCounters) {
    Mesh m = cube_mesh(64, true);
    const Scene s(m.tris());
    auto rays = random_rays(20000, 20, 44, 31);  // inside the sphere (radius 32 at 32)
    std::vector<Hit> h1(rays.size()), h2(rays.size());
    std::vector<TraceCounters> c(rays.size());
    CpuTraceOptions o;
    o.threads = 1;
    o.counters = c.data();
    const CpuTraceStats s1 = trace_cwbvh_cpu(s.wide.nodes.data(), s.wide.nodes.size(), s.wide.tris.data(),
                                             s.wide.tris.size(), rays.data(), h1.data(), rays.size(), o);
    o.threads = 2;
    o.counters = nullptr;
    const CpuTraceStats s2 = trace_cwbvh_cpu(s.wide.nodes.data(), s.wide.nodes.size(), s.wide.tris.data(),
                                             s.wide.tris.size(), rays.data(), h2.data(), rays.size(), o);
    EXPECT_EQ(std::memcmp(h1.data(), h2.data(), h1.size() * sizeof(Hit)), 0);
    EXPECT_EQ(s1.hits, rays.size());  // all origins inside the closed sphere
    EXPECT_EQ(s1.nodes_visited, s2.nodes_visited);
    uint64_t nodes = 0;
    for (const auto& x : c) nodes += x.nodes;
    EXPECT_EQ(nodes, s1.nodes_visited);
    EXPECT_EQ(s1.stack_overflows + s1.bad_indices + s1.invalid_rays, 0u);
}

// Directions with tiny (subnormal) components: RN(1/d) overflows, the slab arithmetic of
// both node tests gives up on that axis, and they must still cull there by the segment's
// reach (axis_range.h): a hit beyond FLT_MAX is no hit (spec/rays.md), so a ray moves at
// most |d| FLT_MAX along such an axis. Before, such a ray visited every node of the tree
// (bunny: 5,515 nodes and 56,737 triangle tests per ray).
//  (1) An axis-parallel ray and the same ray with subnormal instead of zero components
//      visit about as many nodes, and the subnormal ones hit what the oracle hits.
//  (2) A ray whose every component is subnormal moves at most 2^-127 * 2^128 per axis:
//      from the sphere's inside it touches only the few boxes around its origin.
//  (3) Huge components (|d| > 2^126: RN(1/d) is subnormal, also given up): a ray along
//      d * 2^100 is the same segment as along d. On the huge axis the swept range culls
//      only what lies behind the origin (the segment reaches FLT_MAX * 2^126 there), so
//      such a ray visits more than along d, but not the whole tree (before: 6x the nodes
//      and 38x the triangle tests of the ray along d).
TEST(Traverse, TinyAndHugeDirectionComponentsStillCull) {
    Mesh m = cube_mesh(48, true);  // closed sphere, radius 24 at 24 (27,648 triangles)
    const Scene s(m.tris());
    std::mt19937 rng(77);
    std::uniform_real_distribution<float> pos(15, 33), unit(0.5f, 1.0f);
    auto sign = [&] { return (rng() & 1) ? 1.0f : -1.0f; };
    auto subnormal = [&] { return sign() * std::ldexp(unit(rng), -127 - int(rng() % 22)); };
    struct Cost {
        uint64_t nodes[2] = {}, tris[2] = {};  // CWBVH, BVH2
    };
    Cost zero, tiny, all_tiny, unit_dir, huge;
    std::vector<Ray> tiny_rays, all_tiny_rays, huge_rays;
    auto trace = [&](const Ray& r, Cost& c) {
        Hit h;
        TraceCounters k{};
        EXPECT_EQ((s.trace<TriangleTest::kWatertight, HitMode::kClosest>(r, h, &k)), TraceStatus::kOk);
        c.nodes[0] += k.nodes;
        c.tris[0] += k.triangles;
        EXPECT_EQ((s.trace2<TriangleTest::kWatertight, HitMode::kClosest>(r, h, &k)), TraceStatus::kOk);
        c.nodes[1] += k.nodes;
        c.tris[1] += k.triangles;
    };
    const int n = 1000;
    for (int i = 0; i < n; ++i) {
        Ray r{{pos(rng), pos(rng), pos(rng)}, 0.0f, {0, 0, 0}, INFINITY};
        const int k = int(rng() % 3);
        for (int a = 0; a < 3; ++a) r.dir[a] = a == k ? sign() : sign() * 0.0f;
        trace(r, zero);
        for (int a = 0; a < 3; ++a)
            if (a != k) r.dir[a] = subnormal();
        trace(r, tiny);
        tiny_rays.push_back(r);
        for (int a = 0; a < 3; ++a) r.dir[a] = subnormal();
        trace(r, all_tiny);
        all_tiny_rays.push_back(r);
        for (int a = 0; a < 3; ++a) r.dir[a] = sign() * unit(rng);
        trace(r, unit_dir);
        for (int a = 0; a < 3; ++a) r.dir[a] = std::ldexp(r.dir[a], 100);  // the same segment
        r.dir[k] = std::ldexp(r.dir[k], 27);  // |d| > 2^126 on one axis: RN(1/d) is subnormal
        trace(r, huge);
        huge_rays.push_back(r);
    }
    const char* kernel[2] = {"CWBVH", "BVH2"};
    for (int b = 0; b < 2; ++b) {
        std::printf("%s nodes/ray: axis-parallel %.1f, subnormal off-axis %.1f, all subnormal %.1f; "
                    "unit %.1f, huge %.1f (tris/ray %.1f %.1f %.1f %.1f %.1f)\n",
                    kernel[b], double(zero.nodes[b]) / n, double(tiny.nodes[b]) / n, double(all_tiny.nodes[b]) / n,
                    double(unit_dir.nodes[b]) / n, double(huge.nodes[b]) / n, double(zero.tris[b]) / n,
                    double(tiny.tris[b]) / n, double(all_tiny.tris[b]) / n, double(unit_dir.tris[b]) / n,
                    double(huge.tris[b]) / n);
        EXPECT_LE(double(tiny.nodes[b]), 1.05 * double(zero.nodes[b]) + n) << kernel[b];
        EXPECT_LE(double(tiny.tris[b]), 1.05 * double(zero.tris[b]) + n) << kernel[b];
        EXPECT_LE(all_tiny.nodes[b], zero.nodes[b]) << kernel[b];
        EXPECT_LE(all_tiny.tris[b], zero.tris[b]) << kernel[b];
        EXPECT_LE(double(huge.nodes[b]), 3.0 * double(unit_dir.nodes[b]) + n) << kernel[b];
        EXPECT_LE(double(huge.tris[b]), 10.0 * double(unit_dir.tris[b]) + n) << kernel[b];
    }
    for (bool bvh2 : {false, true}) {
        for (auto* set : {&tiny_rays, &all_tiny_rays, &huge_rays}) {
            set->resize(300);  // the exact oracle is the slow part
            const Agreement a = closest_vs_oracle<TriangleTest::kWatertight>(s, *set, bvh2);
            print(bvh2 ? "BVH2 extreme directions vs oracle" : "CWBVH extreme directions vs oracle", a);
            EXPECT_EQ(a.errors(), 0u);
            EXPECT_LE(a.skipped_fraction(), 0.01);
        }
    }
}

// The reach's two edges, each once missed by the first version of it (a review, 2026-11-27):
//  (1) tmin < 0: the segment extends behind the origin, so an axis without slab culling
//      stays open. enable_fast_node_test (the GPU lanes, query.h, every traversal given the
//      scene's NodeScale) once cleared the open bits, and the hit at t = -8.5e37 behind the
//      origin was culled there while the CPU reference found it.
//  (2) A hit whose exact t lies between FLT_MAX and 2^128 rounds to t = FLT_MAX, a hit
//      (spec/rays.md); a reach cut at FLT_MAX culled it.
TEST(Traverse, ReachKeepsHitsBehindTheOriginAndUpToTwoToThe128) {
    auto quad = [](float x, uint32_t prim, std::vector<TriangleRecord>& t) {
        const float a[3] = {x, -1, -1}, b[3] = {x, 1, -1}, c[3] = {x, 1, 1}, d[3] = {x, -1, 1};
        t.push_back(make_tri(a, b, c, prim));
        t.push_back(make_tri(a, c, d, prim + 1));
    };
    struct Case {
        const char* what;
        float quad_x;
        Ray ray;
        float t;  // the hit's t
    };
    const float tiny = std::ldexp(1.0f, -140);
    const float far_x = -(std::ldexp(1.0f, -25) + std::ldexp(1.0f, -40));
    const Case cases[] = {
        {"tmin -inf, subnormal direction, hit behind the origin", -std::ldexp(1.0f, -14),
         Ray{{0, 0, 0}, -INFINITY, {tiny, tiny / 2, tiny / 4}, INFINITY}, -std::ldexp(1.0f, -14) / tiny},
        {"tmin -3e38", -std::ldexp(1.0f, -14), Ray{{0, 0, 0}, -3e38f, {tiny, tiny / 2, tiny / 4}, INFINITY},
         -std::ldexp(1.0f, -14) / tiny},
        {"exact t in (FLT_MAX, 2^128)", far_x, Ray{{-1, 0.1f, 0.2f}, 0, {std::ldexp(1.0f, -128), 0, 0}, INFINITY},
         FLT_MAX},
    };
    for (const Case& c : cases) {
        std::vector<TriangleRecord> tris = random_soup(3000, 40, 1, 5);  // clutter at 0..40
        for (auto& t : tris)
            for (float* v : {t.v0, t.v1, t.v2}) v[0] += 100;  // away from the quad
        quad(c.quad_x, 1000000, tris);
        const Scene s(tris);
        const NodeScale scale = node_scale(s.wide.nodes.data(), s.wide.nodes.size());
        ASSERT_NE(scale.usable, 0u);
        Hit h;
        EXPECT_EQ((s.trace<TriangleTest::kWatertight, HitMode::kClosest>(c.ray, h)), TraceStatus::kOk);
        EXPECT_GE(h.prim, 1000000u) << c.what << ": CPU reference";
        EXPECT_EQ(h.t, c.t) << c.what;
        LocalStack<kCpuStackSize> stack;
        Hit hs;
        traverse_cwbvh<TriangleTest::kWatertight, HitMode::kClosest>(
            s.wide.nodes.data(), uint32_t(s.wide.nodes.size()), s.wide.tris.data(), uint32_t(s.wide.tris.size()),
            c.ray, hs, stack, nullptr, NoPostpone(), scale);
        EXPECT_GE(hs.prim, 1000000u) << c.what << ": with the scene's NodeScale (the kernels' set-up)";
        EXPECT_EQ(hs.t, c.t) << c.what;
        Hit h2;
        s.trace2<TriangleTest::kWatertight, HitMode::kClosest>(c.ray, h2);
        EXPECT_GE(h2.prim, 1000000u) << c.what << ": BVH2";
        NodeRay nr = make_node_ray(c.ray);
        const uint32_t open = ~nr.reach_axis_bits() & 7u;
        enable_fast_node_test(nr, scale, c.ray.dir, c.ray.tmin == 0.0f ? 0.0f : c.ray.tmin);
        EXPECT_EQ(~nr.reach_axis_bits() & 7u, open) << c.what << ": enable_fast_node_test keeps the open axes";
    }
}

}  // namespace
}  // namespace cwbvh::test
