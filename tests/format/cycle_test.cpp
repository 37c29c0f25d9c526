// Rule 5105 (a node's child_base is greater than its own index) is what keeps the wide
// tree free of cycles: with it, every edge points forward and the traversal, the deep
// check and the forward depth pass terminate. The validate tests cover the root pointing
// at itself; here the other shapes of a backward child_base (cycles through the root,
// cycles off the tree, a node among its own children, a backward edge closing no cycle),
// each in a file where nothing else is wrong (every non-root node has exactly one parent,
// every triangle is in one leaf), so that a validator checking child_base at the root
// alone, or only for self loops, accepts them. The control: the same nodes without the
// back edge validate or have only unreached nodes.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "cwbvh/format/node_decode.h"
#include "cwbvh/loader/loader.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

/// Per node: {child_base, internal children} (no internal child when the count is 0).
using Edges = std::vector<std::pair<uint32_t, int>>;

/// One node per entry of `edges`: internal children in slots 0.., one leaf triangle
/// (TRIS record i) in slot 7; all boxes the unit cube.
SceneData tree(const Edges& edges) {
    SceneData s;
    for (uint32_t i = 0; i < edges.size(); ++i) {
        CwbvhNode n = test::unit_leaf_node(i, 7);
        const auto [base, internal] = edges[i];
        for (int c = 0; c < internal && c < 7; ++c) test::set_unit_internal(n, c);  // slot 7 holds the leaf
        if (internal > 0) n.child_base = base;
        s.nodes.push_back(n);
        test::add_unit_triangle(s, i);
    }
    test::close_unit_scene(s);
    return s;
}

struct Cycle {
    const char* name;
    Edges edges;
    uint32_t back_node;     ///< the node whose child_base points back (at or before itself)
    uint32_t control_rule;  ///< the verdict with that back edge removed (0: valid)
};

const std::vector<Cycle>& cycles() {
    constexpr uint32_t kValid = 0, kOrphan = rule::kNodeParents;
    static const std::vector<Cycle> c = {
        {"node 1 points back to the root", {{1, 1}, {0, 1}}, 1, kValid},
        {"three nodes round through the root", {{1, 1}, {2, 1}, {0, 1}}, 2, kValid},
        {"back edge to the root from a deeper branch", {{1, 2}, {3, 1}, {0, 0}, {0, 1}}, 3, kValid},
        {"node 2 is its own child (off the tree)", {{1, 1}, {0, 0}, {2, 1}}, 2, kOrphan},
        {"nodes 2 and 3 are each other's child (off the tree)", {{1, 1}, {0, 0}, {3, 1}, {2, 1}}, 3, kOrphan},
        {"node 2 is among its own children (off the tree)", {{1, 1}, {0, 0}, {2, 2}, {0, 0}}, 2, kOrphan},
        // No cycle, but the parent-before-child order the forward passes rely on is broken.
        {"node 3's child is node 1 (0 -> 2 -> 3 -> 1)", {{2, 1}, {0, 0}, {3, 1}, {1, 1}}, 3, kOrphan},
    };
    return c;
}

TEST(Cycle, EveryShapeIsRejectedByTheChildOrderRule) {
    for (const Cycle& c : cycles()) {
        SCOPED_TRACE(c.name);
        const Result r = test::check(test::file_bytes(tree(c.edges)));
        EXPECT_FALSE(r.ok()) << "a file with a backward child_base validated";
        EXPECT_EQ(r.rule, rule::kNodeChildOrder) << r.describe();
        EXPECT_NE(r.message.find("node " + std::to_string(c.back_node) + ":"), std::string::npos) << r.message;
    }
}

TEST(Cycle, TheLoaderRefusesEveryShape) {
    for (const Cycle& c : cycles()) {
        SCOPED_TRACE(c.name);
        const std::string path = test::write_temp("cycle.cwbvh", test::file_bytes(tree(c.edges)));
        const auto f = File::open(path);
        ASSERT_FALSE(f.ok()) << "the loader opened a file with a backward child_base";
        EXPECT_EQ(f.error().rule, rule::kNodeChildOrder) << f.error().describe();
    }
}

// The control: the back edge is the only thing wrong in each file above. Removed, the
// tree validates, or (off-tree shapes) the nodes it reached are reported unreached (5106).
TEST(Cycle, WithoutTheBackEdgeTheFileIsValidOrHasOrphans) {
    for (const Cycle& c : cycles()) {
        SCOPED_TRACE(c.name);
        Edges e = c.edges;
        e[c.back_node] = {0, 0};
        const Result r = test::check(test::file_bytes(tree(e)));
        EXPECT_EQ(r.rule, c.control_rule) << r.describe();
        EXPECT_EQ(r.ok(), c.control_rule == 0) << r.describe();
    }
}

}  // namespace
}  // namespace cwbvh
