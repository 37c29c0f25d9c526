// Collapse tests: DP optimality against brute force (Ylitie et al. 2017, 3.1),
// root forced internal, structural invariants, deep trees, bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "../result_util.h"
#include "cwbvh/compiler/collapse.h"
#include "wide/wide_test_util.h"

namespace cwbvh::compiler {
namespace {

using wide_test::SplitMode;

CollapseConfig config_of(CollapseKind kind) {
    CollapseConfig c;
    c.kind = kind;
    return c;
}

// Structural invariants of any collapse result.
void check_structure(const BinaryBvh& binary, const WideBvh& wide, size_t triangles) {
    ASSERT_FALSE(wide.nodes.empty());
    std::set<uint32_t> prims;
    std::vector<int> parents(wide.nodes.size(), 0);
    for (const WideNode& n : wide.nodes) {
        EXPECT_GE(n.child_count(), 1);
        int leaf_tris = 0;
        for (const WideChild& ch : n.slots) {
            if (ch.kind == WideChild::kInternal) {
                ASSERT_LT(ch.node, wide.nodes.size());
                ++parents[ch.node];
            } else if (ch.kind == WideChild::kLeaf) {
                EXPECT_GE(ch.ref_count, 1u);
                EXPECT_LE(ch.ref_count, 3u);
                leaf_tris += int(ch.ref_count);
                std::set<uint32_t> in_leaf;
                for (uint32_t k = 0; k < ch.ref_count; ++k) {
                    prims.insert(wide.leaf_refs[ch.first_ref + k]);
                    EXPECT_TRUE(in_leaf.insert(wide.leaf_refs[ch.first_ref + k]).second) << "duplicate in leaf";
                }
            }
        }
        EXPECT_LE(leaf_tris, 24);
    }
    EXPECT_EQ(parents[0], 0);
    for (size_t i = 1; i < parents.size(); ++i) EXPECT_EQ(parents[i], 1);
    EXPECT_EQ(prims.size(), triangles);
    for (size_t i = 0; i < binary.nodes.size(); ++i) {
        if (!binary.nodes[i].is_leaf()) continue;
        ASSERT_LT(wide.binary_leaf_ref[i], wide.leaf_refs.size());
        EXPECT_EQ(wide.leaf_refs[wide.binary_leaf_ref[i]], binary.nodes[i].prim());
    }
}

TEST(Collapse, DpMatchesBruteForceOnTinyTrees) {
    int trees = 0;
    for (uint32_t seed = 1; seed <= 60; ++seed) {
        const size_t n = 2 + seed % 11;  // 2..12 leaves
        const Scene scene = wide_test::random_scene(n, seed, 10.0f, 3.0f);
        const SplitMode mode = seed % 3 == 0   ? SplitMode::kMedian
                               : seed % 3 == 1 ? SplitMode::kRandom
                                               : SplitMode::kChain;
        const BinaryBvh binary = wide_test::build_binary(scene, mode, seed);
        for (float c_prim : {0.3f, 1.0f, 0.05f}) {
            CollapseConfig cfg;
            cfg.cost_prim = c_prim;
            WideBvh wide;
            std::string error;
            ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, cfg, wide), error)) << error;
            check_structure(binary, wide, n);
            const double root_area = binary.nodes[0].box.half_area();
            const double dp = sah_cost_wide(wide, cfg.cost_node, cfg.cost_prim) * root_area;
            const double brute = wide_test::brute_force_min_cost(binary, cfg.cost_node, cfg.cost_prim, 3);
            EXPECT_NEAR(dp, brute, 1e-9 * brute) << "seed " << seed << " n " << n << " c_prim " << c_prim;
            cfg.kind = kCollapseGreedy;
            WideBvh greedy;
            ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, cfg, greedy), error)) << error;
            check_structure(binary, greedy, n);
            EXPECT_GE(sah_cost_wide(greedy, cfg.cost_node, cfg.cost_prim) * root_area, dp * (1 - 1e-12));
            ++trees;
        }
    }
    EXPECT_EQ(trees, 180);
}

TEST(Collapse, DpMatchesBruteForceWithDuplicateReferences) {
    for (uint32_t seed = 1; seed <= 20; ++seed) {
        const size_t n = 3 + seed % 6;
        const Scene scene = wide_test::random_scene(n, seed + 100, 10.0f, 3.0f);
        std::vector<uint32_t> refs;
        for (uint32_t i = 0; i < n; ++i) refs.push_back(i);
        for (uint32_t i = 0; i < 4; ++i) refs.push_back(uint32_t((seed + i) % n));  // spatial-split duplicates
        const BinaryBvh binary = wide_test::build_binary(scene, refs, SplitMode::kRandom, seed);
        WideBvh wide;
        std::string error;
        ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, CollapseConfig{}, wide), error)) << error;
        check_structure(binary, wide, n);
        const double dp = sah_cost_wide(wide, 1.0f, 0.3f) * binary.nodes[0].box.half_area();
        // Same float constants as the config (0.3f is not 0.3).
        EXPECT_NEAR(dp, wide_test::brute_force_min_cost(binary, 1.0f, 0.3f, 3), 1e-9 * dp) << seed;
    }
}

TEST(Collapse, DuplicatesInOneLeafAreStoredOnce) {
    const Scene scene = wide_test::random_scene(1, 5);
    const BinaryBvh binary = wide_test::build_binary(scene, {0, 0, 0}, SplitMode::kMedian);
    for (CollapseKind kind : {kCollapseOptimal, kCollapseGreedy}) {
        WideBvh wide;
        std::string error;
        ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, config_of(kind), wide), error)) << error;
        // Root forced internal over (leaf 0) and (leaf 0, leaf 0): two leaves,
        // the second holding its two references of triangle 0 once.
        ASSERT_EQ(wide.nodes.size(), 1u);
        ASSERT_EQ(wide.nodes[0].child_count(), 2);
        ASSERT_EQ(wide.leaf_refs.size(), 2u);
        EXPECT_EQ(wide.nodes[0].slots[1].ref_count, 1u);
        EXPECT_EQ(wide.binary_leaf_ref[3], wide.binary_leaf_ref[4]);
    }
}

TEST(Collapse, RootIsAlwaysInternal) {
    for (size_t n : {1, 2, 3}) {
        const Scene scene = wide_test::random_scene(n, 7);
        const BinaryBvh binary = wide_test::build_binary(scene);
        for (CollapseKind kind : {kCollapseOptimal, kCollapseGreedy}) {
            WideBvh wide;
            std::string error;
            ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, config_of(kind), wide), error)) << error;
            ASSERT_EQ(wide.nodes.size(), 1u) << n;
            const WideNode& root = wide.nodes[0];
            // One triangle: a single leaf child. More: the DP gives every
            // triangle its own leaf (cheaper: each leaf box is smaller); the
            // greedy collapse keeps one leaf per binary child of the root.
            EXPECT_EQ(root.child_count(), n == 1 ? 1 : kind == kCollapseOptimal ? int(n) : 2);
            for (const WideChild& ch : root.slots)
                if (ch.kind != WideChild::kEmpty) {
                    EXPECT_EQ(ch.kind, WideChild::kLeaf);
                }
            check_structure(binary, wide, n);
        }
    }
}

TEST(Collapse, DeepChainIsIterative) {
    const size_t n = 30000;  // binary depth 30000
    const Scene scene = wide_test::random_scene(n, 3);
    const BinaryBvh binary = wide_test::build_binary(scene, SplitMode::kChain);
    for (CollapseKind kind : {kCollapseOptimal, kCollapseGreedy}) {
        WideBvh wide;
        std::string error;
        ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, config_of(kind), wide), error)) << error;
        check_structure(binary, wide, n);
    }
}

TEST(Collapse, RejectsMalformedBinaryTrees) {
    const Scene scene = wide_test::random_scene(8, 9);
    const BinaryBvh good = wide_test::build_binary(scene);
    WideBvh wide;
    std::string error;
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(BinaryBvh{}, CollapseConfig{}, wide), error));
    BinaryBvh bad = good;
    bad.nodes[0].child[1] = 99999;
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(bad, CollapseConfig{}, wide), error));
    EXPECT_NE(error.find("bad child index"), std::string::npos) << error;
    bad = good;
    bad.nodes[0].child[1] = bad.nodes[0].child[0];
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(bad, CollapseConfig{}, wide), error));
    bad = good;
    bad.nodes[3].box.lo[1] = std::nanf("");
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(bad, CollapseConfig{}, wide), error));
    bad = good;
    bad.nodes.push_back(bad.nodes.back());  // unreachable node
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(bad, CollapseConfig{}, wide), error));
    CollapseConfig cfg;
    cfg.max_leaf = 4;
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(good, cfg, wide), error));
    cfg = CollapseConfig{};
    cfg.kind = CollapseKind(7);
    EXPECT_FALSE(::cwbvh::test::ok(collapse_wide(good, cfg, wide), error));
}

TEST(Collapse, DpBeatsGreedyOnRandomScene) {
    const Scene scene = wide_test::random_scene(5000, 11);
    const BinaryBvh binary = wide_test::build_binary(scene);
    WideBvh dp, greedy;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, config_of(kCollapseOptimal), dp), error)) << error;
    ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, config_of(kCollapseGreedy), greedy), error)) << error;
    // The DP minimises SAH, not the node count (which can come out either way).
    EXPECT_LT(sah_cost_wide(dp, 1, 0.3f), sah_cost_wide(greedy, 1, 0.3f));
    EXPECT_GT(wide_avg_children(dp), wide_avg_children(greedy));
}

}  // namespace
}  // namespace cwbvh::compiler
