// Tree depths by one forward pass: a parent always precedes its children, so
// a node's depth is final when the pass reaches it.
#include "cwbvh/format/tree_depth.h"

#include <algorithm>
#include <vector>

namespace cwbvh {

uint32_t wide_tree_depth(std::span<const CwbvhNode> nodes) {
    if (nodes.empty()) return 0;
    std::vector<uint32_t> depth(nodes.size(), 1);
    uint32_t deepest = 1;
    for (size_t i = 0; i < nodes.size(); ++i) {
        const CwbvhNode& n = nodes[i];
        const uint32_t internal = uint32_t(__builtin_popcount(n.imask));
        for (uint32_t c = 0; c < internal; ++c) {
            const size_t child = size_t(n.child_base) + c;
            if (child <= i || child >= nodes.size()) continue;  // structure is checked elsewhere
            depth[child] = depth[i] + 1;
            deepest = std::max(deepest, depth[child]);
        }
    }
    return deepest;
}

uint32_t bvh2_tree_depth(std::span<const Bvh2Node> nodes) {
    if (nodes.empty()) return 0;
    std::vector<uint32_t> depth(nodes.size(), 1);
    uint32_t deepest = 1;
    for (size_t i = 0; i < nodes.size(); ++i) {
        for (int32_t child : nodes[i].child) {
            const uint32_t d = depth[i] + 1;
            deepest = std::max(deepest, d);
            if (child < 0 || size_t(child) <= i || size_t(child) >= nodes.size()) continue;
            depth[size_t(child)] = d;
        }
    }
    return deepest;
}

}  // namespace cwbvh
