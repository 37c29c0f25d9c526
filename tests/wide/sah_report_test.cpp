// The wide SAH report (spec 3.5, sah_report.h): the formula on decoded boxes,
// its split into the node and triangle terms, and how it relates to the same
// formula on the exact boxes (the collapse DP's boxes).
#include <gtest/gtest.h>

#include <filesystem>

#include "../result_util.h"
#include "cwbvh/compiler/auction.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/encode.h"
#include "cwbvh/compiler/sah_report.h"
#include "scene_corpus.h"
#include "wide/wide_test_util.h"

namespace cwbvh::compiler {
namespace {

TEST(SahReport, HandComputedOnGridAlignedBoxes) {
    // Boxes on the quantization grid decode exactly: root frame [0,255]^3
    // (cell 1), node 1 frame [0,110]^3 (cell 0.5).
    Scene scene;
    scene.vertices = {{0, 0, 0},       {255, 0, 0},     {0, 255, 255},  {0, 0, 0},
                      {10, 0, 0},      {0, 10, 10},     {100, 100, 100}, {110, 100, 100},
                      {100, 110, 110}};
    scene.indices = {{0, 1, 2}, {3, 4, 5}, {6, 7, 8}};
    scene.sources.resize(3);
    WideBvh wide;
    wide.leaf_refs = {0, 1, 2};
    wide.nodes.resize(2);
    BinaryBvh boxes;
    wide.binary = &boxes;
    wide.nodes[1].slots[0] = wide_test::leaf_of(scene, boxes, 1, 1);
    wide.nodes[1].slots[1] = wide_test::leaf_of(scene, boxes, 2, 1);
    Aabb box1 = wide.box(wide.nodes[1].slots[0]);
    box1.grow(wide.box(wide.nodes[1].slots[1]));
    wide.nodes[1].bnode = wide_test::add_box(boxes, box1);
    wide.nodes[0].slots[0] = wide_test::leaf_of(scene, boxes, 0, 1);
    wide.nodes[0].slots[1].kind = WideChild::kInternal;
    wide.nodes[0].slots[1].node = 1;
    wide.nodes[0].slots[1].bnode = wide.nodes[1].bnode;
    Aabb box0 = wide.box(wide.nodes[0].slots[0]);
    box0.grow(box1);
    wide.nodes[0].bnode = wide_test::add_box(boxes, box0);
    EncodedTree tree;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(encode_cwbvh(wide, scene, tree), error)) << error;
    const double root = 3.0 * 255 * 255;  // half area of [0,255]^3
    const WideSahParts parts = report_sah_wide_parts(tree.nodes, wide.box(wide.nodes[0]));
    EXPECT_DOUBLE_EQ(parts.internal, 1.0 + 3.0 * 110 * 110 / root);
    EXPECT_DOUBLE_EQ(parts.leaf, 1.0 + 2 * 300.0 / root);
    EXPECT_DOUBLE_EQ(parts.total, parts.internal + parts.leaf);
    EXPECT_EQ(report_sah_wide(tree.nodes, wide.box(wide.nodes[0])), parts.total);
    // Exact boxes give the same figures here (nothing is inflated).
    EXPECT_DOUBLE_EQ(sah_cost_wide(wide, 1, 0), parts.internal);
    EXPECT_DOUBLE_EQ(sah_cost_wide(wide, 0, 1), parts.leaf);
    EXPECT_EQ(report_sah_wide_parts({}, wide.box(wide.nodes[0])).total, 0.0);
}

TEST(SahReport, DecodedTermsBoundTheExactOnes) {
    for (uint32_t seed = 1; seed <= 12; ++seed) {
        const Scene scene = wide_test::random_scene(300 + 50 * seed, seed, 100.0f, 1.0f + float(seed % 4));
        const BinaryBvh binary = wide_test::build_binary(scene, wide_test::SplitMode::kMedian, seed);
        for (CollapseKind kind : {kCollapseOptimal, kCollapseGreedy}) {
            for (float c_prim : {0.3f, 1.0f}) {
                CollapseConfig cfg;
                cfg.kind = kind;
                cfg.cost_prim = c_prim;
                WideBvh wide;
                EncodedTree tree;
                std::string error;
                ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, cfg, wide), error)) << error;
                assign_slots(wide);
                ASSERT_TRUE(::cwbvh::test::ok(encode_cwbvh(wide, scene, tree), error)) << error;
                const Aabb& root = wide.box(wide.nodes[0]);
                const WideSahParts parts = report_sah_wide_parts(tree.nodes, root);
                EXPECT_EQ(report_sah_wide(tree.nodes, root), parts.total);
                EXPECT_NEAR(parts.total, parts.internal + parts.leaf, 1e-12 * parts.total);
                // Decoded boxes contain the exact ones: each term can only grow.
                const double exact_internal = sah_cost_wide(wide, 1, 0), exact_leaf = sah_cost_wide(wide, 0, 1);
                EXPECT_GE(parts.internal, exact_internal * (1 - 1e-12)) << seed;
                EXPECT_GE(parts.leaf, exact_leaf * (1 - 1e-12)) << seed;
            }
        }
    }
}

// The report counts nodes and triangles alike (C_node = C_prim = 1), so the
// DP run with C_prim = 1 minimises it on the exact boxes: on the bunny its
// decoded figure is below the default C_prim = 0.3 one, which trades SAH for
// wider nodes.
TEST(SahReport, BunnyCostModelMatchingTheReportLowersIt) {
    const std::string path = ::cwbvh::test::corpus_scene("bunny.obj");
    CWBVH_REQUIRE_SCENE(path);
    Scene scene;
    ASSERT_TRUE(wide_test::read_obj(path, scene));
    BinaryBvh binary;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(build_sbvh(scene, SbvhConfig{}, binary), error)) << error;
    double report[2], exact[2], children[2];
    const float c_prims[2] = {0.3f, 1.0f};
    for (int k = 0; k < 2; ++k) {
        CollapseConfig cfg;
        cfg.cost_prim = c_prims[k];
        WideBvh wide;
        EncodedTree tree;
        ASSERT_TRUE(::cwbvh::test::ok(collapse_wide(binary, cfg, wide), error)) << error;
        assign_slots(wide);
        ASSERT_TRUE(::cwbvh::test::ok(encode_cwbvh(wide, scene, tree), error)) << error;
        report[k] = report_sah_wide(tree.nodes, binary.nodes[0].box);
        exact[k] = sah_cost_wide(wide, 1, 1);
        children[k] = tree.avg_children;
        std::printf("bunny C_prim %.1f: report SAH %.4f (exact boxes %.4f), avg children %.3f\n", double(c_prims[k]),
                    report[k], exact[k], children[k]);
    }
    EXPECT_LT(exact[1], exact[0]);
    EXPECT_LT(report[1], report[0]);
    EXPECT_GT(children[0], children[1]);
}

}  // namespace
}  // namespace cwbvh::compiler
