// Rules 5113 and 5606: the trees are bounded in depth so that the traversal
// kernels' 64-entry stacks can never overflow on a valid file.
#include <gtest/gtest.h>

#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/tree_depth.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

/// A chain of `levels` wide nodes: each has its child node in slot 0 and one
/// leaf triangle in slot 1; the last has only the leaf. Boxes all equal.
SceneData wide_chain(uint32_t levels) {
    SceneData s;
    for (uint32_t i = 0; i < levels; ++i) {
        CwbvhNode n = test::unit_leaf_node(i, 1);
        if (i + 1 < levels) {
            test::set_unit_internal(n, 0);
            n.child_base = i + 1;
        }
        s.nodes.push_back(n);
        test::add_unit_triangle(s, i);
    }
    test::close_unit_scene(s);
    return s;
}

/// A BVH2 chain: node i has node i+1 as child[0] and leaf i as child[1].
std::vector<Bvh2Node> bvh2_chain(uint32_t internal_nodes) {
    std::vector<Bvh2Node> v(internal_nodes);
    for (uint32_t i = 0; i < internal_nodes; ++i) {
        Bvh2Node& n = v[i];
        n = Bvh2Node{};
        n.c0_hi_x = n.c0_hi_y = n.c1_hi_x = n.c1_hi_y = 1.0f;
        n.child[0] = i + 1 < internal_nodes ? int32_t(i + 1) : ~int32_t(i + 1);
        n.child[1] = ~int32_t(i);
    }
    return v;
}

TEST(Depth, WideTreeAtTheLimitIsValidOneDeeperIsNot) {
    const SceneData ok = wide_chain(kMaxWideDepth);
    EXPECT_EQ(wide_tree_depth(ok.nodes), kMaxWideDepth);
    const Result r_ok = test::check(test::file_bytes(ok));
    EXPECT_TRUE(r_ok.ok()) << r_ok.describe();

    const SceneData deep = wide_chain(kMaxWideDepth + 1);
    const Result r = test::check(test::file_bytes(deep));
    EXPECT_EQ(r.rule, rule::kNodeDepth) << r.describe();
}

TEST(Depth, Bvh2AtTheLimitIsValidOneDeeperIsNot) {
    // kMaxBvh2Depth levels including the leaves: kMaxBvh2Depth - 1 internal nodes.
    SceneData ok = wide_chain(kMaxBvh2Depth / 4);
    SceneData deep = ok;
    auto trimmed = [](SceneData& s, uint32_t internal) {
        // BVH2 leaves index TRIS: make sure there are enough records.
        while (s.triangles.size() < internal + 1) s.triangles.push_back(s.triangles.back());
        s.bvh2 = bvh2_chain(internal);
    };
    trimmed(ok, kMaxBvh2Depth - 1);
    EXPECT_EQ(bvh2_tree_depth(ok.bvh2), kMaxBvh2Depth);
    trimmed(deep, kMaxBvh2Depth);
    EXPECT_EQ(bvh2_tree_depth(deep.bvh2), kMaxBvh2Depth + 1);
    // Only the BVH2 section is checked here (extra TRIS records are not in any leaf).
    ValidateOptions o;
    o.sections = kMaskBvh2 | kMaskTriangles;
    std::vector<uint8_t> f_ok = test::file_bytes(ok), f_deep = test::file_bytes(deep);
    const Result r_ok = validate(std::span<const uint8_t>(f_ok), o);
    EXPECT_TRUE(r_ok.ok()) << r_ok.describe();
    const Result r = validate(std::span<const uint8_t>(f_deep), o);
    EXPECT_EQ(r.rule, rule::kBvh2Depth) << r.describe();
}

}  // namespace
}  // namespace cwbvh
