// SAH-optimal binary -> 8-wide collapse: the dynamic program of Ylitie,
// Karras, Laine 2017, section 3.1.
//
// For every binary node n and i = 1..7, C(n, i) is the smallest SAH cost of
// representing n's subtree as a forest of at most i roots (each root a wide
// leaf or a wide internal node):
//   C(n, 1) = min(C_leaf(n), C_internal(n))
//   C(n, i) = min(C(n, 1), min_{k=1..i-1} C(left, k) + C(right, i-k))   (i > 1)
//   C_leaf(n)     = C_prim * T(n) * A(n)  if n holds <= max_leaf references, else inf
//   C_internal(n) = C_node * A(n) + min_{k=1..7} C(left, k) + C(right, 8-k)
// with A the surface area and T(n) the number of distinct triangles of n's
// leaves (references of one triangle inside a leaf are stored once). A binary
// leaf has C(n, i) = C_leaf(n). The root is forced internal (the traversal
// starts with an internal node) and the tree is rebuilt by backtracking the
// stored decisions from the root. O(n * 7 * 7) time, 72 bytes per binary node.
#include <limits>

#include "cwbvh/compiler/collapse.h"

#include <cassert>

namespace cwbvh::compiler::detail {
namespace {

constexpr int kMaxRoots = kWidth - 1;  // a child subtree of a wide node gets <= 7 roots

struct NodeDp {
    double cost[kMaxRoots];    ///< cost[i-1] = C(n, i)
    uint8_t split[kMaxRoots];  ///< split[i-1]: 0 = one root (n itself), k = k roots to the left child
    uint8_t internal_split;    ///< C_internal: roots given to the left child (right gets 8 - k)
    bool as_leaf;              ///< C(n, 1) is realised by a wide leaf
};

}  // namespace

bool collapse_optimal(const BinaryBvh& binary, const CollapseConfig& config,
                      const std::vector<uint32_t>& ref_count, WideBvh& out, std::string& error) {
    const size_t n = binary.nodes.size();
    const double c_node = config.cost_node, c_prim = config.cost_prim;
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<NodeDp> dp(n);

    // Children have larger indices than parents (checked): a reverse sweep is
    // an iterative post-order, with no recursion depth limit.
    for (size_t idx = n; idx-- > 0;) {
        const BinaryNode& b = binary.nodes[idx];
        NodeDp& d = dp[idx];
        const double area = b.box.half_area();
        const double leaf_cost = ref_count[idx] <= uint32_t(config.max_leaf)
                                     ? c_prim * distinct_leaf_triangles(binary, uint32_t(idx)) * area
                                     : inf;
        if (b.is_leaf()) {
            for (int i = 0; i < kMaxRoots; ++i) {
                d.cost[i] = leaf_cost;
                d.split[i] = 0;
            }
            d.as_leaf = true;
            d.internal_split = 0;
            continue;
        }
        const NodeDp& l = dp[b.child[0]];
        const NodeDp& r = dp[b.child[1]];
        double best_children = inf;
        int best_k = 1;
        for (int k = 1; k <= kMaxRoots; ++k) {  // left gets k roots, right 8 - k (both >= 1)
            const double c = l.cost[k - 1] + r.cost[kWidth - k - 1];
            if (c < best_children) {
                best_children = c;
                best_k = k;
            }
        }
        const double internal_cost = c_node * area + best_children;
        d.internal_split = uint8_t(best_k);
        // Ties go to the leaf: same SAH, one node fewer.
        d.as_leaf = leaf_cost <= internal_cost;
        d.cost[0] = d.as_leaf ? leaf_cost : internal_cost;
        d.split[0] = 0;
        for (int i = 2; i <= kMaxRoots; ++i) {
            double best = d.cost[0];
            int split = 0;
            for (int k = 1; k < i; ++k) {
                const double c = l.cost[k - 1] + r.cost[i - k - 1];
                if (c < best) {
                    best = c;
                    split = k;
                }
            }
            d.cost[i - 1] = best;
            d.split[i - 1] = uint8_t(split);
        }
    }

    // Backtracking: create wide nodes top-down. Each wide node gets the roots
    // of its binary node's two child forests.
    struct Work {
        uint32_t binary;
        uint32_t wide;
    };
    std::vector<Work> work;
    out.nodes.emplace_back();
    out.nodes[0].box = binary.nodes[0].box;
    if (binary.nodes[0].is_leaf()) {
        // Root forced internal: one wide leaf child holding the single reference.
        out.nodes[0].slots[0] = make_wide_leaf(binary, 0, out);
        return true;
    }
    work.push_back({0, 0});
    uint32_t roots[kWidth];
    while (!work.empty()) {
        const Work w = work.back();
        work.pop_back();
        const BinaryNode& b = binary.nodes[w.binary];
        int count = 0;
        // expand(m, i): the roots of m's optimal forest of at most i roots.
        // Depth <= 7 (every split hands >= 1 root to each side).
        auto expand = [&](auto&& self, uint32_t m, int i) -> void {
            const int s = dp[m].split[i - 1];
            if (s == 0) {
                roots[count++] = m;
                return;
            }
            self(self, binary.nodes[m].child[0], s);
            self(self, binary.nodes[m].child[1], i - s);
        };
        const int k = dp[w.binary].internal_split;
        expand(expand, b.child[0], k);
        expand(expand, b.child[1], kWidth - k);
        assert(count >= 2 && count <= kWidth);
        uint32_t triangles = 0;
        for (int c = 0; c < count; ++c) {
            const uint32_t m = roots[c];
            if (dp[m].as_leaf) {
                out.nodes[w.wide].slots[c] = make_wide_leaf(binary, m, out);
                triangles += out.nodes[w.wide].slots[c].ref_count;
            } else {
                uint32_t child = 0;
                if (!add_internal_child(binary, m, w.wide, c, out, child, error)) return false;
                work.push_back({m, child});
            }
        }
        // 8 leaves of <= 3 triangles: the 5-bit offsets always suffice.
        assert(triangles <= uint32_t(kMaxNodeTriangles));
        (void)triangles;
    }
    return true;
}

}  // namespace cwbvh::compiler::detail
