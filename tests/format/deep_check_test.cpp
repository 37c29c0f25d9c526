// deep_check (cwbvh validate --deep): accepts a correct tree, and catches
// geometry that escapes its boxes even when the file is structurally valid.
#include <gtest/gtest.h>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/format/deep_check.h"

namespace cwbvh {
namespace {

TEST(DeepCheck, AcceptsTheSyntheticScene) {
    const SceneData s = make_synthetic_scene();
    DeepCheckStats st;
    const Result r = deep_check(s.nodes, s.triangles, s.triangles.size() ? s.triangles.size() : 0, &st);
    // The synthetic scene stores every triangle once: prim ids 0..n-1.
    EXPECT_TRUE(r.ok()) << r.describe();
    EXPECT_GT(st.unsplit_triangles, 0u);
}

TEST(DeepCheck, TriangleOutsideItsLeafIsCaught) {
    SceneData s = make_synthetic_scene();
    ASSERT_FALSE(s.triangles.empty());
    s.triangles[0].v1[0] += 1000.0f;  // still a valid file, but the triangle pokes out of every box
    const Result r = deep_check(s.nodes, s.triangles, s.triangles.size());
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.message.find("D2"), std::string::npos) << r.message;
}

TEST(DeepCheck, UnreferencedStoredTriangleIsCaught) {
    const SceneData s = make_synthetic_scene();
    const Result r = deep_check(s.nodes, s.triangles, s.triangles.size() + 1);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.message.find("D4"), std::string::npos) << r.message;
}

TEST(DeepCheck, SplitTriangleNeedsItsReferencesToCoverIt) {
    // Records 0 and n-1 (in different leaves, far apart) become the two
    // references of one triangle stretched from record 0's region to record
    // n-1's: each leaf box meets the triangle, but the middle of the triangle
    // lies in neither box chain. (Stored triangle n-1 is dropped from the count.)
    SceneData s = make_synthetic_scene();
    const size_t n = s.triangles.size();
    ASSERT_GE(n, 3u);
    TriangleRecord stretched = s.triangles[0];
    for (int a = 0; a < 3; ++a) {
        stretched.v1[a] = s.triangles[n - 1].v1[a];
        stretched.v2[a] = s.triangles[n - 1].v2[a];
    }
    stretched.prim = s.triangles[0].prim;
    const uint32_t last_prim = s.triangles[n - 1].prim;
    s.triangles[0] = stretched;
    s.triangles[n - 1] = stretched;
    // Keep ids dense: the id that lost its record takes over the largest id's records.
    for (auto& t : s.triangles)
        if (t.prim == uint32_t(n - 1)) t.prim = last_prim;
    const Result r = deep_check(s.nodes, s.triangles, n - 1);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(r.message.find("D3"), std::string::npos) << r.message;
}

}  // namespace
}  // namespace cwbvh
