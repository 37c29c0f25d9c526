// build_sbvh: tree validity, degenerate inputs, budget, spatial splits and
// determinism across thread counts.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>

#include "../result_util.h"
#include "build/test_mesh.h"
#include "cwbvh/compiler/build.h"

namespace cwbvh::compiler {
namespace {

using test::add_triangle;

BinaryBvh build_ok(const Scene& s, SbvhConfig cfg = {}) {
    BinaryBvh bvh;
    std::string error;
    EXPECT_TRUE(::cwbvh::test::ok(build_sbvh(s, cfg, bvh), error)) << error;
    std::string verror;
    EXPECT_TRUE(::cwbvh::test::ok(validate_binary_bvh(s, bvh, 4000), verror)) << verror;
    EXPECT_EQ(bvh.references, (bvh.nodes.size() + 1) / 2);
    EXPECT_LE(double(bvh.references), (1.0 + cfg.max_reference_growth) * double(s.triangle_count()));
    return bvh;
}

bool identical(const BinaryBvh& a, const BinaryBvh& b) {
    if (a.nodes.size() != b.nodes.size() || a.references != b.references ||
        a.spatial_splits != b.spatial_splits || a.object_splits != b.object_splits)
        return false;
    static_assert(sizeof(BinaryNode) == 32);  // no padding: bitwise compare is meaningful
    return std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(BinaryNode)) == 0;
}

TEST(Sbvh, EmptySceneIsAnError) {
    Scene s;
    BinaryBvh bvh;
    std::string error;
    EXPECT_FALSE(::cwbvh::test::ok(build_sbvh(s, {}, bvh), error));
    EXPECT_FALSE(error.empty());
}

TEST(Sbvh, OneTriangle) {
    Scene s;
    add_triangle(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    const BinaryBvh bvh = build_ok(s);
    ASSERT_EQ(bvh.nodes.size(), 1u);
    EXPECT_TRUE(bvh.nodes[0].is_leaf());
}

TEST(Sbvh, TwoTriangles) {
    Scene s;
    add_triangle(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    add_triangle(s, {0, 0, 1}, {1, 0, 1}, {0, 1, 1});
    const BinaryBvh bvh = build_ok(s);
    EXPECT_EQ(bvh.nodes.size(), 3u);
}

TEST(Sbvh, AllTrianglesIdentical) {
    Scene s;
    for (int i = 0; i < 1000; ++i) add_triangle(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    const BinaryBvh bvh = build_ok(s);
    EXPECT_EQ(bvh.references, 1000u);
    // Median splits: depth stays logarithmic.
    std::vector<int> depth(bvh.nodes.size(), 0);
    int max_depth = 0;
    for (size_t i = 0; i < bvh.nodes.size(); ++i) {
        if (bvh.nodes[i].is_leaf()) continue;
        for (uint32_t c : bvh.nodes[i].child) { depth[c] = depth[i] + 1; max_depth = std::max(max_depth, depth[c]); }
    }
    EXPECT_LE(max_depth, 12);
}

TEST(Sbvh, CoplanarStack) {
    Scene s;  // 1000 overlapping triangles in the plane z = 0
    for (int i = 0; i < 1000; ++i) {
        const float o = float(i) * 1e-3f;
        add_triangle(s, {o, 0, 0}, {1 + o, 0, 0}, {o, 1, 0});
    }
    build_ok(s);
}

TEST(Sbvh, FlatScene) {
    Scene s = test::random_soup(5000, 7, 0.05f);
    for (Vec3& v : s.vertices) v[2] = 3.0f;
    build_ok(s);
}

TEST(Sbvh, RandomSoup) {
    const Scene s = test::random_soup(20000, 11, 0.2f);
    SbvhConfig every_node;  // the spatial-split machinery at every node size
    every_node.min_spatial_refs = 2;
    const BinaryBvh bvh = build_ok(s, every_node);
    EXPECT_GT(bvh.spatial_splits, 0u);
}

// The default skips spatial splits below 16 references (SbvhConfig::
// min_spatial_refs): on the adversarial scenes, where the duplicates the budget
// allows are made in small nodes, the tree may get no spatial split at all, but
// is never worse than the object-split tree and stays within 1% of the
// every-node build's binary SAH.
TEST(Sbvh, MinSpatialRefsCostsLittle) {
    for (const Scene& s : {test::random_soup(20000, 11, 0.2f), test::sliver_scene(2000)}) {
        SbvhConfig every_node;
        every_node.min_spatial_refs = 2;
        SbvhConfig objects_only;
        objects_only.split_alpha = 1.0f;
        const double sah_default = sah_cost_binary(build_ok(s));
        const double sah_every = sah_cost_binary(build_ok(s, every_node));
        const double sah_objects = sah_cost_binary(build_ok(s, objects_only));
        std::printf("min_spatial_refs: SAH default %.4f, every node %.4f, object splits only %.4f\n", sah_default,
                    sah_every, sah_objects);
        EXPECT_LE(sah_default, sah_objects);
        EXPECT_LE(sah_default, sah_every * 1.01);
    }
}

TEST(Sbvh, SpatialSplitsOnSlivers) {
    const Scene s = test::sliver_scene(2000);
    // Every sliver spans the scene: the first useful spatial split duplicates
    // all of them, more than the default budget (0.2) allows; give it room.
    SbvhConfig roomy;
    roomy.max_reference_growth = 1.0;
    roomy.min_spatial_refs = 2;  // the machinery at every node size
    const BinaryBvh bvh = build_ok(s, roomy);
    EXPECT_GT(bvh.spatial_splits, 0u);
    EXPECT_GT(bvh.references, s.triangle_count());
    SbvhConfig plain;
    plain.split_alpha = 1.0f;  // object splits only
    const BinaryBvh obj = build_ok(s, plain);
    EXPECT_EQ(obj.spatial_splits, 0u);
    EXPECT_EQ(obj.references, s.triangle_count());
    std::printf("sbvh slivers: refs %llu, spatial %llu, SAH %.3f (object splits only: %.3f)\n",
                (unsigned long long)bvh.references, (unsigned long long)bvh.spatial_splits,
                sah_cost_binary(bvh), sah_cost_binary(obj));
    EXPECT_LT(sah_cost_binary(bvh), sah_cost_binary(obj));
}

TEST(Sbvh, BudgetIsRespected) {
    const Scene s = test::sliver_scene(2000);
    for (double g : {0.0, 0.01, 0.1}) {
        SbvhConfig cfg;
        cfg.max_reference_growth = g;
        const BinaryBvh bvh = build_ok(s, cfg);
        EXPECT_LE(double(bvh.references), (1.0 + g) * 2000.0);
        if (g == 0.0) {
            EXPECT_EQ(bvh.spatial_splits, 0u);
        }
    }
}

TEST(Sbvh, HugeAndOffsetCoordinates) {
    for (float scale : {1e20f, 1e-20f}) {
        Scene s = test::sliver_scene(500);
        for (Vec3& v : s.vertices) for (float& c : v) c *= scale;
        build_ok(s);
    }
    Scene s = test::random_soup(3000, 5, 0.05f);
    for (Vec3& v : s.vertices) for (float& c : v) c = 1e7f + c * 1e3f;
    build_ok(s);
}

TEST(Sbvh, SahFormula) {
    Scene s;
    add_triangle(s, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    add_triangle(s, {0, 0, 1}, {1, 0, 1}, {0, 1, 1});
    const BinaryBvh bvh = build_ok(s);
    // root: 1x1x1 box; leaves: 1x1x0 boxes = area ratio 1/3 each.
    EXPECT_NEAR(sah_cost_binary(bvh, 1.0f, 0.3f), 1.0 + 2 * double(0.3f) / 3.0, 1e-12);
}

TEST(Sbvh, RealMeshes) {
    for (const char* name : {"dragon_res4.obj", "bunny.obj"}) {
        Scene s;
        test::read_corpus_obj(name, s);
        if (test::corpus_obj_missing_or_broken()) return;
        const auto t0 = std::chrono::steady_clock::now();
        BinaryBvh bvh;
        std::string error;
        ASSERT_TRUE(::cwbvh::test::ok(build_sbvh(s, {}, bvh), error)) << error;
        const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::string verror;
        EXPECT_TRUE(::cwbvh::test::ok(validate_binary_bvh(s, bvh, 20000), verror)) << name << ": " << verror;
        std::printf("%s: %zu tris, %.3f s, refs %llu (+%.2f%%), spatial %llu, object %llu, SAH %.3f\n", name,
                    s.triangle_count(), sec, (unsigned long long)bvh.references,
                    100.0 * (double(bvh.references) / double(s.triangle_count()) - 1.0),
                    (unsigned long long)bvh.spatial_splits, (unsigned long long)bvh.object_splits,
                    sah_cost_binary(bvh));
    }
}

/// The SBVH of `s` is the same for 1, 2 and the default number of threads, and has spatial splits.
void expect_deterministic(const Scene& s, const std::string& what) {
    SCOPED_TRACE(what);
    SbvhConfig one, two, dflt;
    one.threads = 1;
    two.threads = 2;
    BinaryBvh a, b, c;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(build_sbvh(s, one, a), error)) << error;
    ASSERT_TRUE(::cwbvh::test::ok(build_sbvh(s, two, b), error)) << error;
    ASSERT_TRUE(::cwbvh::test::ok(build_sbvh(s, dflt, c), error)) << error;
    EXPECT_TRUE(identical(a, b));
    EXPECT_TRUE(identical(a, c));
    EXPECT_GT(a.spatial_splits, 0u);
}

TEST(Sbvh, DeterministicAcrossThreadCounts) {
    test::on_soup_then_corpus_obj(test::random_soup(50000, 3, 0.1f), "bunny.obj", expect_deterministic);
}

}  // namespace
}  // namespace cwbvh::compiler
