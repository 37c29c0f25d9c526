// collapse_wide(): input checks and helpers shared by the optimal (DP) and
// greedy collapses. Ylitie, Karras, Laine 2017, section 3.1.
#include "cwbvh/compiler/collapse.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace cwbvh::compiler {
namespace detail {

Result check_binary(const BinaryBvh& binary, std::vector<uint32_t>& ref_count) {
    const size_t n = binary.nodes.size();
    if (n == 0) return Result::fail(Status::kInvalidArgument, 0, "binary BVH has no nodes");
    if (n >= size_t(kInvalidIndex)) return Result::fail(Status::kInvalidArgument, 0, "binary BVH has too many nodes");
    std::vector<uint8_t> parents(n, 0);
    for (size_t i = 0; i < n; ++i) {
        const BinaryNode& node = binary.nodes[i];
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(node.box.lo[a]) || !std::isfinite(node.box.hi[a]) || node.box.lo[a] > node.box.hi[a]) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "binary BVH node " + std::to_string(i) + " has an empty or non-finite box");
            }
        }
        if (node.is_leaf()) {
            if (node.prim() == kInvalidIndex) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "binary BVH leaf " + std::to_string(i) + " has no triangle");
            }
            continue;
        }
        for (int c = 0; c < 2; ++c) {
            const uint32_t ch = node.child[c];
            // Children after their parent (depth-first order) rules out cycles.
            if (ch == kInvalidIndex || ch <= i || ch >= n) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "binary BVH node " + std::to_string(i) + " has a bad child index");
            }
            if (parents[ch]++ != 0) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "binary BVH node " + std::to_string(ch) + " has more than one parent");
            }
        }
    }
    for (size_t i = 1; i < n; ++i) {
        if (parents[i] != 1) {
            return Result::fail(Status::kInvalidArgument, 0,
                                "binary BVH node " + std::to_string(i) + " is unreachable from the root");
        }
    }
    // Children have larger indices: a reverse sweep is a post-order.
    ref_count.assign(n, 0);
    for (size_t i = n; i-- > 0;) {
        const BinaryNode& node = binary.nodes[i];
        if (node.is_leaf()) {
            ref_count[i] = 1;
        } else {
            const uint64_t sum = uint64_t(ref_count[node.child[0]]) + ref_count[node.child[1]];
            ref_count[i] = uint32_t(std::min<uint64_t>(sum, std::numeric_limits<uint32_t>::max()));
        }
    }
    return Result::success();
}

namespace {
// Binary leaves under `node`, left first. Callers use this on subtrees of
// <= 3 references (called for most binary nodes by the DP), so the explicit
// stack lives on the C++ stack; a deeper subtree spills to the heap.
template <class F>
void for_each_leaf(const BinaryBvh& binary, uint32_t node, F&& f) {
    constexpr size_t kInline = 32;
    uint32_t inline_stack[kInline];
    std::vector<uint32_t> spill;
    size_t n = 0;
    auto push = [&](uint32_t v) {
        if (n < kInline) inline_stack[n] = v;
        else spill.push_back(v);
        ++n;
    };
    auto pop = [&]() {
        --n;
        if (n < kInline) return inline_stack[n];
        const uint32_t v = spill.back();
        spill.pop_back();
        return v;
    };
    push(node);
    while (n > 0) {
        const uint32_t i = pop();
        const BinaryNode& b = binary.nodes[i];
        if (b.is_leaf()) {
            f(i);
        } else {
            push(b.child[1]);
            push(b.child[0]);
        }
    }
}
}  // namespace

uint32_t distinct_leaf_triangles(const BinaryBvh& binary, uint32_t node) {
    uint32_t prims[kMaxNodeTriangles];
    uint32_t count = 0, total = 0;
    for_each_leaf(binary, node, [&](uint32_t leaf) {
        const uint32_t p = binary.nodes[leaf].prim();
        ++total;
        if (std::find(prims, prims + count, p) == prims + count && count < kMaxNodeTriangles) prims[count++] = p;
    });
    return total > kMaxNodeTriangles ? total : count;
}

WideChild make_wide_leaf(const BinaryBvh& binary, uint32_t node, WideBvh& wide) {
    WideChild child;
    child.kind = WideChild::kLeaf;
    child.box = binary.nodes[node].box;
    child.first_ref = uint32_t(wide.leaf_refs.size());
    for_each_leaf(binary, node, [&](uint32_t leaf) {
        const uint32_t p = binary.nodes[leaf].prim();
        // Spatial splits can put two references of one triangle in the same
        // leaf: store it once (the DP's leaf cost counts distinct triangles).
        uint32_t k = child.first_ref;
        while (k < wide.leaf_refs.size() && wide.leaf_refs[k] != p) ++k;
        if (k == wide.leaf_refs.size()) wide.leaf_refs.push_back(p);
        if (!wide.binary_leaf_ref.empty()) wide.binary_leaf_ref[leaf] = k;
    });
    child.ref_count = uint8_t(wide.leaf_refs.size() - child.first_ref);  // <= max_leaf <= 3
    return child;
}

Result add_internal_child(const BinaryBvh& binary, uint32_t binary_node, uint32_t parent, int slot, WideBvh& out,
                        uint32_t& child) {
    if (out.nodes.size() >= size_t(kInvalidIndex)) {
        return Result::fail(Status::kInvalidArgument, 0, "collapse: too many wide nodes");
    }
    child = uint32_t(out.nodes.size());
    out.nodes.emplace_back();
    out.nodes[child].box = binary.nodes[binary_node].box;
    WideChild& s = out.nodes[parent].slots[size_t(slot)];
    s.kind = WideChild::kInternal;
    s.box = binary.nodes[binary_node].box;
    s.node = child;
    return Result::success();
}

}  // namespace detail

Result collapse_wide(const BinaryBvh& binary, const CollapseConfig& config, WideBvh& out,
                   Progress* progress) {
    out = WideBvh{};
    if (config.max_leaf < 1 || config.max_leaf > kMaxLeafTriangles) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "collapse: max_leaf must be 1.." + std::to_string(kMaxLeafTriangles));
    }
    if (!(config.cost_node >= 0.0f) || !(config.cost_prim >= 0.0f) || !std::isfinite(config.cost_node) ||
        !std::isfinite(config.cost_prim))
        return Result::fail(Status::kInvalidArgument, 0, "collapse: cost model constants must be finite and >= 0");
    std::vector<uint32_t> ref_count;
    if (Result r = detail::check_binary(binary, ref_count); !r.ok()) return r;
    if (config.binary_leaf_refs) out.binary_leaf_ref.assign(binary.nodes.size(), kInvalidIndex);
    switch (config.kind) {
        case kCollapseOptimal: return detail::collapse_optimal(binary, config, std::move(ref_count), out, progress);
        case kCollapseGreedy: return detail::collapse_greedy(binary, config, ref_count, out, progress);
    }
    return Result::fail(Status::kInvalidArgument, 0, "collapse: unknown collapse kind");
}

}  // namespace cwbvh::compiler
