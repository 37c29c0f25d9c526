// collapse_wide(): input checks and helpers shared by the optimal (DP) and
// greedy collapses. Ylitie, Karras, Laine 2017, section 3.1.
#include "cwbvh/compiler/collapse.h"

#include <algorithm>
#include <cmath>
#include <atomic>
#include <limits>
#include <utility>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cwbvh/compiler/parallel_exact.h"

namespace cwbvh::compiler {
namespace detail {

namespace {

/// The serial structure check (the first failing node in index order
/// reports); the parallel check below runs it again only to name a failure.
Result check_structure_serial(const BinaryBvh& binary) {
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
    return Result::success();
}

/// Reference counts by a reverse sweep (children have larger indices: a post-order).
void count_refs_serial(const BinaryBvh& binary, size_t begin, size_t end, std::vector<uint32_t>& ref_count) {
    for (size_t i = end; i-- > begin;) {
        const BinaryNode& node = binary.nodes[i];
        if (node.is_leaf()) {
            ref_count[i] = 1;
        } else {
            const uint64_t sum = uint64_t(ref_count[node.child[0]]) + ref_count[node.child[1]];
            ref_count[i] = uint32_t(std::min<uint64_t>(sum, std::numeric_limits<uint32_t>::max()));
        }
    }
}

constexpr size_t kCheckGrain = 1 << 14;

}  // namespace

bool preorder_cut(const BinaryBvh& binary, size_t max_nodes, std::vector<uint32_t>& top,
                  std::vector<NodeRange>& tasks) {
    top.clear();
    tasks.clear();
    std::vector<NodeRange> pending{{0, uint32_t(binary.nodes.size())}};
    while (!pending.empty()) {
        const NodeRange r = pending.back();
        pending.pop_back();
        const BinaryNode& b = binary.nodes[r.begin];
        if (b.is_leaf() || r.end - r.begin <= max_nodes) {
            tasks.push_back(r);
            continue;
        }
        const uint32_t c0 = b.child[0], c1 = b.child[1];
        if (c0 != r.begin + 1 || !(c1 > c0 && c1 < r.end)) return false;  // not preorder
        top.push_back(r.begin);
        pending.push_back({c1, r.end});
        pending.push_back({c0, c1});
    }
    return true;
}

Result check_binary(const BinaryBvh& binary, std::vector<uint32_t>& ref_count) {
    const size_t n = binary.nodes.size();
    if (n == 0) return Result::fail(Status::kInvalidArgument, 0, "binary BVH has no nodes");
    if (n >= size_t(kInvalidIndex)) return Result::fail(Status::kInvalidArgument, 0, "binary BVH has too many nodes");
    // In parallel: every node's own checks, and its children's parent marks
    // (bit 0: a parent, bit 1: a second one). Any failure: the serial check
    // names the same first failure as before.
    std::vector<uint8_t> parents(n, 0);
    std::atomic<bool> bad{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kCheckGrain), [&](const tbb::blocked_range<size_t>& r) {
        bool local_bad = false;
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const BinaryNode& node = binary.nodes[i];
            for (int a = 0; a < 3; ++a) {
                local_bad |= !std::isfinite(node.box.lo[a]) || !std::isfinite(node.box.hi[a]) ||
                             node.box.lo[a] > node.box.hi[a];
            }
            if (node.is_leaf()) {
                local_bad |= node.prim() == kInvalidIndex;
                continue;
            }
            for (int c = 0; c < 2; ++c) {
                const uint32_t ch = node.child[c];
                if (ch == kInvalidIndex || ch <= i || ch >= n) {
                    local_bad = true;
                    continue;
                }
                mark_parent(parents[ch]);
            }
        }
        if (local_bad) bad.store(true, std::memory_order_relaxed);
    });
    if (!bad.load() && lowest_failing(n, kCheckGrain, [&](size_t i) { return i > 0 && parents[i] != 1; }) < n) bad = true;
    std::vector<uint8_t>().swap(parents);
    if (bad.load()) {
        Result r = check_structure_serial(binary);
        if (r.ok()) r = Result::fail(Status::kInternal, 0, "binary BVH check: parallel and serial checks disagree");
        return r;
    }
    ref_count.assign(n, 0);
    // A valid tree: every node has one parent with a smaller index. Preorder
    // subtrees (what both builders write) are counted in parallel, each by a
    // reverse sweep of its index range; any other order by one serial sweep.
    std::vector<uint32_t> top;
    std::vector<NodeRange> tasks;
    if (!preorder_cut(binary, size_t(1) << 16, top, tasks)) {
        count_refs_serial(binary, 0, n, ref_count);
        return Result::success();
    }
    std::atomic<bool> escaped{false};
    tbb::parallel_for(size_t(0), tasks.size(), [&](size_t t) {
        const NodeRange r = tasks[t];
        // Children outside the task's range: not a preorder subtree.
        for (size_t i = r.begin; i < r.end; ++i) {
            const BinaryNode& node = binary.nodes[i];
            if (!node.is_leaf() && (node.child[0] >= r.end || node.child[1] >= r.end)) {
                escaped.store(true, std::memory_order_relaxed);
                return;
            }
        }
        count_refs_serial(binary, r.begin, r.end, ref_count);
    });
    if (escaped.load()) {
        count_refs_serial(binary, 0, n, ref_count);
        return Result::success();
    }
    for (size_t k = top.size(); k-- > 0;) count_refs_serial(binary, top[k], top[k] + 1, ref_count);
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
    uint32_t cursor = uint32_t(wide.leaf_refs.size());
    wide.leaf_refs.resize(size_t(cursor) + distinct_leaf_triangles(binary, node));
    return make_wide_leaf_at(binary, node, wide, cursor);
}

WideChild make_wide_leaf_at(const BinaryBvh& binary, uint32_t node, WideBvh& wide, uint32_t& cursor) {
    WideChild child;
    child.kind = WideChild::kLeaf;
    child.bnode = node;
    child.first_ref = cursor;
    for_each_leaf(binary, node, [&](uint32_t leaf) {
        const uint32_t p = binary.nodes[leaf].prim();
        // Spatial splits can put two references of one triangle in the same
        // leaf: store it once (the DP's leaf cost counts distinct triangles).
        uint32_t k = child.first_ref;
        while (k < cursor && wide.leaf_refs[k] != p) ++k;
        if (k == cursor) wide.leaf_refs[cursor++] = p;
        if (!wide.binary_leaf_ref.empty()) wide.binary_leaf_ref[leaf] = k;
    });
    child.ref_count = uint8_t(cursor - child.first_ref);  // <= max_leaf <= 3
    return child;
}

Result add_internal_child(uint32_t binary_node, uint32_t parent, int slot, WideBvh& out, uint32_t& child) {
    if (out.nodes.size() >= size_t(kInvalidIndex)) {
        return Result::fail(Status::kInvalidArgument, 0, "collapse: too many wide nodes");
    }
    child = uint32_t(out.nodes.size());
    out.nodes.emplace_back();
    link_internal_child(binary_node, parent, slot, child, out);
    return Result::success();
}

void link_internal_child(uint32_t binary_node, uint32_t parent, int slot, uint32_t child, WideBvh& out) {
    out.nodes[child].bnode = binary_node;
    WideChild& s = out.nodes[parent].slots[size_t(slot)];
    s.kind = WideChild::kInternal;
    s.bnode = binary_node;
    s.node = child;
}

}  // namespace detail

Result collapse_wide(const BinaryBvh& binary, const CollapseConfig& config, WideBvh& out,
                   Progress* progress) {
    out = WideBvh{};
    out.binary = &binary;
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
