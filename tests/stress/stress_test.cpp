// Stress suite on compiled scenes: real meshes (bunny, dragon_res4, dragon_res2)
// and generated adversarial meshes are compiled in-test by the compiler library,
// written, re-opened with File::open, and traced with random, camera and diffuse
// rays (and, on grids, rays through vertices and edges exactly). Each traversal is
// checked against the exact oracle (culled: stress_support.h) and against Embree
// rtcIntersect1/rtcOccluded1; the mismatch table is printed:
//   fmiss  oracle hit, traversal missed      fhit  oracle miss, traversal hit
//   wprim  reported triangle not among the closest (and not hit within tol of it)
//   terr   right triangle, |t - exact t| > 4 oracle tolerances (2^-16 of
//          |org| + scene extent, in units of |dir|); maxterr in oracle tolerances
//   ties   another triangle at the same t within the tolerance
// near-end cases (the deciding hit within the tolerance of tmin/tmax, e.g. the
// surface a diffuse ray leaves) are accepted either way and only counted.
// Asserted: the watertight CWBVH and BVH2 traversals (closest and any) are clean,
// BVH2 and CWBVH agree bitwise on t and on hit/miss, and every closest-hit
// disagreement with Embree is a tie or a case where the oracle says Embree is wrong.
// The fast (Moller-Trumbore) test and Embree are reported, not asserted. The GPU
// kernel's lane code (the warp model: sm_90's fast node test where a ray allows it,
// postponing, dynamic fetch) is held to the BVH2's standard: bitwise differences from
// the CPU traversal are counted, and each must have both answers right by the oracle.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <random>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/warp_model.h"
#include "stress/stress_support.h"
#include "scene_corpus.h"

namespace cwbvh::stress {
namespace {

using test::Mesh;

struct RaySet {
    std::string name;
    std::vector<Ray> rays;
};

std::vector<RaySet> standard_rays(const File& f, size_t n_random, uint32_t cam_size) {
    const SceneBounds& b = *f.bounds();
    std::vector<RaySet> sets;
    sets.push_back({"random", random_rays(b, n_random, 12345)});
    Camera cam = default_camera(b);
    std::vector<Ray> primary = camera_rays(cam, cam_size, cam_size);
    const auto nodes = f.nodes();
    const auto tris = f.triangles();
    DiffuseRays d = diffuse_rays(nodes.data(), nodes.size(), tris.data(), tris.size(), primary, 1, 7, 2);
    sets.push_back({"camera", std::move(primary)});
    sets.push_back({"diffuse", std::move(d.rays)});
    return sets;
}

struct Totals {
    Tally wt, fast, bvh2, any, embree, embree_any;
    uint64_t embree_agree = 0, embree_tie = 0, embree_wrong = 0, unexplained = 0;
    uint64_t bvh2_disagree = 0, bvh2_bitwise_differ = 0;
    uint64_t model_differ = 0, model_disagree = 0;  ///< GPU lane code vs CPU: bitwise, not both right
    uint64_t model_fast_steps = 0, model_steps = 0;
};

/// Traces every set by every method, prints the table, returns the totals.
Totals check_scene(const std::string& scene, const File& f, const std::vector<RaySet>& sets) {
    const auto nodes = f.nodes();
    const auto tris = f.triangles();
    const auto bvh2 = f.bvh2();
    const CulledOracle oracle(tris);
    const EmbreePeer embree(tris);
    Totals tot;
    // Every file here is compiled with --keep-sbvh (compile_and_open): no BVH2 is a failure,
    // not a reason to check the CWBVH traversal alone.
    if (bvh2.empty()) {
        ADD_FAILURE() << scene << ": no BVH2 section in a file compiled with --keep-sbvh";
        return tot;
    }
    for (const RaySet& set : sets) {
        const size_t n = set.rays.size();
        std::vector<Hit> wt(n), fast(n), b2(n), any(n);
        CpuTraceOptions o;
        o.threads = 2;
        trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), set.rays.data(), wt.data(), n, o);
        std::vector<Hit> gpu_lanes(n);
        {
            WarpModelOptions mo;
            mo.warps = 64;
            const WarpModelStats ms = model_cwbvh_warps(nodes.data(), nodes.size(), tris.data(), tris.size(),
                                                        set.rays.data(), gpu_lanes.data(), n, mo);
            tot.model_fast_steps += ms.lane_fast_node_steps;
            tot.model_steps += ms.lane_node_steps;
        }
        trace_bvh2_cpu(bvh2.data(), bvh2.size(), tris.data(), tris.size(), set.rays.data(), b2.data(), n, o);
        o.test = TriangleTest::kFast;
        trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), set.rays.data(), fast.data(), n, o);
        o.test = TriangleTest::kWatertight;
        o.mode = HitMode::kAny;
        trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), set.rays.data(), any.data(), n, o);
        Tally s_wt, s_fast, s_b2, s_any, s_em, s_em_any;
        for (size_t i = 0; i < n; ++i) {
            const Ray& r = set.rays[i];
            const test::OracleResult ex = oracle.trace(r);
            classify_closest(r, wt[i], ex, oracle, s_wt);
            classify_closest(r, fast[i], ex, oracle, s_fast);
            classify_any(r, any[i], ex, oracle, s_any);
            classify_closest(r, b2[i], ex, oracle, s_b2);
            // The same triangle test on the same ray gives bitwise equal t for the same
            // triangle; the trees may still differ where a triangle test reports a hit
            // a rounding error outside the triangle's box (the node test culls it in one
            // tree, not the other). So: bitwise differences are counted, and must be
            // explained by both answers being right (checked against the oracle). The
            // GPU lane code is held to the same (its node test has its own false positives).
            auto compare_bitwise = [&](const Hit& other, uint64_t& differ, uint64_t& disagree) {
                const bool same = (wt[i].prim == kMissPrim) == (other.prim == kMissPrim) &&
                                  std::memcmp(&wt[i].t, &other.t, sizeof(float)) == 0;
                if (same) return;
                ++differ;
                Tally a, b;
                classify_closest(r, wt[i], ex, oracle, a);
                classify_closest(r, other, ex, oracle, b);
                if (!a.clean() || !b.clean()) ++disagree;
            };
            compare_bitwise(b2[i], tot.bvh2_bitwise_differ, tot.bvh2_disagree);
            compare_bitwise(gpu_lanes[i], tot.model_differ, tot.model_disagree);
            const Hit e = embree.intersect(r);
            Tally one;
            classify_closest(r, e, ex, oracle, one);
            classify_closest(r, e, ex, oracle, s_em);
            // rtcOccluded1 reports no triangle: a hit stands for the oracle's closest
            // one (or an id of no triangle when the oracle misses: a false hit).
            const Hit ea = embree.occluded(r) ? Hit{0, 0, 0, ex.hit ? ex.prim : kMissPrim - 1} : make_miss();
            classify_any(r, ea, ex, oracle, s_em_any);
            // CWBVH vs Embree, closest hit.
            if (e.prim == wt[i].prim) {
                ++tot.embree_agree;
            } else if (!one.clean()) {
                ++tot.embree_wrong;  // the oracle says Embree is wrong
            } else {
                Tally mine;
                classify_closest(r, wt[i], ex, oracle, mine);
                if (mine.clean()) ++tot.embree_tie;  // both right: a tie or near-end case
                else ++tot.unexplained;
            }
        }
        print_tally(scene, set.name, "cwbvh-wt", s_wt);
        print_tally(scene, set.name, "cwbvh-fast", s_fast);
        print_tally(scene, set.name, "bvh2-wt", s_b2);
        print_tally(scene, set.name, "cwbvh-wt-any", s_any);
        print_tally(scene, set.name, "embree", s_em);
        print_tally(scene, set.name, "embree-any", s_em_any);
        auto add = [](Tally& a, const Tally& b) {
            a.rays += b.rays;
            a.oracle_hits += b.oracle_hits;
            a.agree += b.agree;
            a.ties += b.ties;
            a.false_miss += b.false_miss;
            a.false_hit += b.false_hit;
            a.wrong_prim += b.wrong_prim;
            a.t_error += b.t_error;
            a.near_end += b.near_end;
            a.max_t_err = std::max(a.max_t_err, b.max_t_err);
        };
        add(tot.wt, s_wt);
        add(tot.fast, s_fast);
        add(tot.bvh2, s_b2);
        add(tot.any, s_any);
        add(tot.embree, s_em);
        add(tot.embree_any, s_em_any);
    }
    std::printf("%-22s cwbvh-wt vs embree closest: agree %llu, tie/near-end %llu, embree wrong %llu, unexplained %llu; "
                "bvh2 vs cwbvh: t bitwise differ %llu, unexplained %llu; gpu lane code vs cpu: t bitwise differ %llu, "
                "unexplained %llu (fast node test on %.1f%% of node steps)\n",
                scene.c_str(), (unsigned long long)tot.embree_agree, (unsigned long long)tot.embree_tie,
                (unsigned long long)tot.embree_wrong, (unsigned long long)tot.unexplained,
                (unsigned long long)tot.bvh2_bitwise_differ, (unsigned long long)tot.bvh2_disagree,
                (unsigned long long)tot.model_differ, (unsigned long long)tot.model_disagree,
                tot.model_steps ? 100.0 * double(tot.model_fast_steps) / double(tot.model_steps) : 0.0);
    std::fflush(stdout);
    return tot;
}

void expect_clean(const std::string& scene, const Totals& t) {
    EXPECT_EQ(t.wt.false_miss, 0u) << scene << ": watertight CWBVH false misses";
    EXPECT_TRUE(t.wt.clean()) << scene << ": watertight CWBVH closest hit disagrees with the oracle";
    EXPECT_TRUE(t.any.clean()) << scene << ": watertight CWBVH any hit disagrees with the oracle";
    EXPECT_GT(t.bvh2.rays, 0u) << scene << ": the BVH2 traversal was not checked";
    EXPECT_EQ(t.bvh2.rays, t.wt.rays) << scene << ": the BVH2 traversal did not see every ray";
    EXPECT_TRUE(t.bvh2.clean()) << scene << ": watertight BVH2 disagrees with the oracle";
    EXPECT_EQ(t.bvh2_disagree, 0u) << scene << ": BVH2 and CWBVH traversals differ";
    EXPECT_EQ(t.unexplained, 0u) << scene << ": CWBVH and Embree differ and the oracle does not side with CWBVH";
    EXPECT_EQ(t.model_disagree, 0u) << scene << ": the GPU lane code (warp model) and the CPU traversal differ";
}

bool open_generated(const Mesh& m, const std::string& name, File& f) {
    std::string err;
    const std::string obj = write_obj(m, name);
    if (obj.empty() || !compile_and_open(obj, name, f, err)) {
        ADD_FAILURE() << name << ": " << err;
        return false;
    }
    return true;
}

Mesh soup_mesh(const std::vector<TriangleRecord>& tris) {
    Mesh m;
    for (const TriangleRecord& t : tris) {
        for (const float* v : {t.v0, t.v1, t.v2}) {
            m.idx.push_back(uint32_t(m.v.size() / 3));
            m.v.insert(m.v.end(), v, v + 3);
        }
    }
    return m;
}

class StressTest : public TempDirSuite {
protected:
    static void SetUpTestSuite() { print_tally_header(); }
};

TEST_F(StressTest, WatertightGridVerticesAndEdges) {
    for (bool bumpy : {true, false}) {
        const int n = 24;
        const Mesh m = test::grid_mesh(n, bumpy);
        const std::string name = bumpy ? "grid-bumpy" : "grid-flat-z0";
        File f;
        if (!open_generated(m, name, f)) return;
        std::vector<RaySet> sets = standard_rays(f, 1500, 32);
        sets.push_back({"vert/edge", grid_point_rays(m, n)});
        // In-plane rays on the flat grid: the plane contains the ray, so all miss.
        if (!bumpy) {
            std::vector<Ray> inplane;
            for (int j = 0; j <= n; ++j) {
                const float o[3] = {-1.0f, float(j) + (j % 2 ? 0.5f : 0.0f), 0.0f}, d[3] = {1.0f, 0.25f, 0.0f};
                inplane.push_back(test::make_ray(o, d));
            }
            sets.push_back({"in-plane", inplane});
        }
        expect_clean(name, check_scene(name, f, sets));
    }
}

TEST_F(StressTest, ScaledAndOffsetSpheres) {
    struct Case {
        const char* name;
        double scale, offset;
    };
    const Case cases[] = {{"sphere-1e-20", 1e-20, 0.0},
                          {"sphere-1e+20", 1e20, 0.0},
                          {"sphere-1e-2@1e5", 1e-2, 1e5},
                          {"sphere-4@1e7", 4.0, 1e7}};
    for (const Case& c : cases) {
        Mesh m = test::cube_mesh(12, true);
        m.transform(c.scale, c.offset);
        File f;
        if (!open_generated(m, c.name, f)) continue;
        const Totals t = check_scene(c.name, f, standard_rays(f, 1500, 32));
        expect_clean(c.name, t);
    }
}

// 1e-2 detail at an offset of 1e7 (float spacing 1 there): every triangle
// collapses; the compiler must say so in one clean error, not build an empty tree.
TEST_F(StressTest, DetailBelowFloatSpacingIsAnError) {
    Mesh m = test::cube_mesh(12, true);
    m.transform(1e-2, 1e7);
    File f;
    std::string err;
    EXPECT_FALSE(compile_and_open(write_obj(m, "sphere-1e-2@1e7"), "sphere-1e-2@1e7", f, err));
    EXPECT_NE(err.find("degenerate"), std::string::npos) << err;
}

TEST_F(StressTest, NeedlesSliversStacksDuplicates) {
    // Needles and slivers: long thin triangles, random orientation.
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    std::vector<TriangleRecord> needles;
    for (uint32_t i = 0; i < 2000; ++i) {
        float a[3], b[3], c[3];
        for (int k = 0; k < 3; ++k) {
            a[k] = u(rng) * 4.0f;
            b[k] = a[k] + u(rng) * 3.0f;
            c[k] = 0.5f * (a[k] + b[k]) + u(rng) * ((i % 2) ? 1e-4f : 1e-2f);
        }
        needles.push_back(test::make_tri(a, b, c, i));
    }
    {
        File f;
        if (open_generated(soup_mesh(needles), "needles", f))
            expect_clean("needles", check_scene("needles", f, standard_rays(f, 2000, 32)));
    }
    // Coplanar overlapping stack: 6 shifted copies of a flat grid in z = 0, and
    // exact duplicates (the same triangles three times).
    {
        Mesh stack;
        const Mesh g = test::grid_mesh(8, false);
        for (int c = 0; c < 6; ++c) {
            const uint32_t base = uint32_t(stack.v.size() / 3);
            for (size_t i = 0; i < g.v.size(); i += 3) {
                stack.v.push_back(g.v[i] + 0.25f * c);
                stack.v.push_back(g.v[i + 1] + 0.125f * c);
                stack.v.push_back(0.0f);
            }
            for (uint32_t x : g.idx) stack.idx.push_back(base + x);
        }
        for (int c = 0; c < 2; ++c)
            for (size_t i = 0; i < g.idx.size(); ++i) stack.idx.push_back(g.idx[i]);  // duplicates of copy 0
        File f;
        if (open_generated(stack, "coplanar-stack+dups", f)) {
            std::vector<RaySet> sets = standard_rays(f, 1500, 32);
            sets.push_back({"vert/edge", grid_point_rays(g, 8)});
            expect_clean("coplanar-stack+dups", check_scene("coplanar-stack+dups", f, sets));
        }
    }
}

void real_scene(const std::string& path, const std::string& name, size_t n_random, uint32_t cam) {
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " not installed";  // corpus scenes: checked by the caller
    const auto t0 = std::chrono::steady_clock::now();
    File f;
    std::string err;
    ASSERT_TRUE(compile_and_open(path, name, f, err)) << err;
    const Totals t = check_scene(name, f, standard_rays(f, n_random, cam));
    expect_clean(name, t);
    std::printf("%s: %zu triangles, %.1f s\n", name.c_str(), f.triangles().size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

TEST_F(StressTest, Bunny) { real_scene("/usr/share/glmark2/models/bunny.obj", "bunny", 2000, 40); }
TEST_F(StressTest, DragonRes4) {
    CWBVH_REQUIRE_SCENE(::cwbvh::test::corpus_scene("dragon_res4.glb"));
    real_scene(::cwbvh::test::corpus_scene("dragon_res4.glb"), "dragon_res4", 3000, 48);
}
TEST_F(StressTest, DragonRes2) {
    CWBVH_REQUIRE_SCENE(::cwbvh::test::corpus_scene("dragon_res2.glb"));
    real_scene(::cwbvh::test::corpus_scene("dragon_res2.glb"), "dragon_res2", 800, 24);
}

}  // namespace
}  // namespace cwbvh::stress
