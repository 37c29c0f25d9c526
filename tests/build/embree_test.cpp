// build_embree: validity, spatial splits really happen, determinism.
#include <gtest/gtest.h>

#include <cstring>

#include "../result_util.h"
#include "build/test_mesh.h"
#include "cwbvh/compiler/build.h"

namespace cwbvh::compiler {
namespace {

using test::add_triangle;

BinaryBvh embree_ok(const Scene& s, SbvhConfig cfg = {}) {
    BinaryBvh bvh;
    std::string error;
    EXPECT_TRUE(::cwbvh::test::ok(build_embree(s, cfg, bvh), error)) << error;
    std::string verror;
    EXPECT_TRUE(::cwbvh::test::ok(validate_binary_bvh(s, bvh, 4000), verror)) << verror;
    EXPECT_LE(double(bvh.references), (1.0 + cfg.max_reference_growth) * double(s.triangle_count()));
    return bvh;
}

TEST(Embree, SmallAndDegenerate) {
    Scene one;
    add_triangle(one, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    EXPECT_EQ(embree_ok(one).nodes.size(), 1u);
    Scene two = one;
    add_triangle(two, {0, 0, 1}, {1, 0, 1}, {0, 1, 1});
    EXPECT_EQ(embree_ok(two).nodes.size(), 3u);
    Scene same;
    for (int i = 0; i < 1000; ++i) add_triangle(same, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    embree_ok(same);
    Scene flat = test::random_soup(3000, 7, 0.05f);
    for (Vec3& v : flat.vertices) v[2] = 3.0f;
    embree_ok(flat);
    BinaryBvh bvh;
    std::string error;
    EXPECT_FALSE(::cwbvh::test::ok(build_embree(Scene{}, {}, bvh), error));
}

TEST(Embree, SpatialSplitsHappenOnSlivers) {
    const Scene s = test::sliver_scene(2000);
    const BinaryBvh bvh = embree_ok(s);
    std::printf("embree slivers: refs %llu for %zu tris, spatial %llu, SAH %.3f\n",
                (unsigned long long)bvh.references, s.triangle_count(),
                (unsigned long long)bvh.spatial_splits, sah_cost_binary(bvh));
    EXPECT_GT(bvh.references, s.triangle_count());
    EXPECT_GT(bvh.spatial_splits, 0u);
}

/// build_embree is valid and the same for 1 and 2 threads on `s`.
void expect_deterministic(const Scene& s, const std::string& what) {
    SCOPED_TRACE(what);
    SbvhConfig one, two;
    one.threads = 1;
    two.threads = 2;
    const BinaryBvh a = embree_ok(s, one), b = embree_ok(s, two);
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    EXPECT_EQ(std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(BinaryNode)), 0);
    EXPECT_EQ(a.references, b.references);
}

TEST(Embree, DeterministicAndValidOnRealMesh) {
    test::on_soup_then_corpus_obj(test::random_soup(20000, 3, 0.1f), "dragon_res4.obj", expect_deterministic);
}

}  // namespace
}  // namespace cwbvh::compiler
