// Greedy top-down binary -> 8-wide collapse, the baseline the SAH-optimal DP
// is compared against (Ylitie et al. 2017, section 3.1, citing Wald et al.
// 2008 and Afra et al. 2013): starting from a binary node's two children,
// repeatedly open the child with the largest surface area that is too big to
// be a leaf, until there are 8 children or none can be opened. A subtree with
// <= max_leaf references becomes a wide leaf, any other child a wide node.
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/progress.h"

namespace cwbvh::compiler::detail {

Result collapse_greedy(const BinaryBvh& binary, const CollapseConfig& config,
                     const std::vector<uint32_t>& ref_count, WideBvh& out,
                     Progress* progress) {
    const uint32_t max_leaf = uint32_t(config.max_leaf);
    // Progress, one per binary node: every node is the binary node of a wide
    // node, opened while gathering children, or inside a leaf's subtree
    // (a subtree of r binary leaves has 2r - 1 nodes).
    ProgressBatch visited(progress);
    struct Work {
        uint32_t binary;
        uint32_t wide;
    };
    std::vector<Work> work{{0, 0}};
    out.nodes.emplace_back();
    out.nodes[0].bnode = 0;
    while (!work.empty()) {
        const Work w = work.back();
        work.pop_back();
        const BinaryNode& b = binary.nodes[w.binary];
        uint32_t children[kWidth];
        int count = 0;
        if (b.is_leaf()) {
            children[count++] = w.binary;  // only the root: one leaf child (counted as that leaf)
        } else {
            children[count++] = b.child[0];
            children[count++] = b.child[1];
            visited.add(1);
        }
        while (count < kWidth) {
            int best = -1;
            double best_area = -1.0;
            for (int c = 0; c < count; ++c) {
                if (ref_count[children[c]] <= max_leaf) continue;  // stays a leaf
                const double a = binary.nodes[children[c]].box.half_area();
                if (a > best_area) {  // ties: the first (leftmost) child
                    best_area = a;
                    best = c;
                }
            }
            if (best < 0) break;
            const BinaryNode& open = binary.nodes[children[best]];
            // Replace by its two children, keeping the left-to-right order.
            for (int c = count; c > best + 1; --c) children[c] = children[c - 1];
            children[best] = open.child[0];
            children[best + 1] = open.child[1];
            ++count;
            visited.add(1);
        }
        for (int c = 0; c < count; ++c) {
            const uint32_t m = children[c];
            if (ref_count[m] <= max_leaf) {
                out.nodes[w.wide].slots[c] = make_wide_leaf(binary, m, out);
                visited.add(2 * uint64_t(ref_count[m]) - 1);  // ref_count[m] <= max_leaf: exact
                continue;
            }
            uint32_t child = 0;
            if (Result r = add_internal_child(m, w.wide, c, out, child); !r.ok()) return r;
            work.push_back({m, child});
        }
    }
    return Result::success();
}

}  // namespace cwbvh::compiler::detail
