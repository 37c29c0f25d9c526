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
// stored decisions from the root. O(n * 7 * 7) time.
//
// Memory: the decisions (4 bytes per binary node) are kept for the
// backtracking; the costs C(n, .) are only needed until the parent has used
// them. For a tree in depth-first preorder (what both builders write), the
// reverse sweep finishes a subtree right before its parent needs it, so the
// pending costs form a stack of depth O(tree depth). Any other valid order
// falls back to one cost array per node (56 more bytes per node).
#include <algorithm>
#include <atomic>
#include <limits>
#include <vector>

#include <tbb/parallel_for.h>

#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/progress.h"

#include <cassert>

namespace cwbvh::compiler::detail {
namespace {

constexpr int kMaxRoots = kWidth - 1;  // a child subtree of a wide node gets <= 7 roots

/// One node's decisions, packed into 4 bytes (the decisions of every binary
/// node are the largest array the collapse keeps: 4 instead of 9 bytes per node).
/// Bits 3(i-1) .. 3(i-1)+2: split(i) for i = 1..7 roots (0 = one root, n itself;
/// k = k roots to the left child); bits 21..23: internal_split (C_internal: roots
/// given to the left child, the right gets 8 - k); bit 24: as_leaf (C(n, 1) is
/// realised by a wide leaf).
struct Decision {
    uint32_t bits = 0;
    int split(int i) const { return int((bits >> (3 * (i - 1))) & 7u); }
    int internal_split() const { return int((bits >> 21) & 7u); }
    bool as_leaf() const { return ((bits >> 24) & 1u) != 0; }
    static uint32_t pack_split(int i, int k) { return uint32_t(k) << (3 * (i - 1)); }
    static uint32_t pack_internal_split(int k) { return uint32_t(k) << 21; }
    static uint32_t pack_as_leaf(bool leaf) { return uint32_t(leaf) << 24; }
};
static_assert(kMaxRoots == 7 && kWidth == 8, "Decision packs 7 splits of 3 bits and a 3-bit internal split");

struct Costs {
    double c[kMaxRoots];  ///< c[i-1] = C(n, i)
};

/// Pending costs as a stack (preorder trees): put() pushes, take() pops and
/// checks that the top belongs to the node asked for.
class CostStack {
public:
    void put(uint32_t node, const Costs& c) { stack_.push_back({node, c}); }
    bool empty() const { return stack_.empty(); }
    bool take(uint32_t node, Costs& out) {
        if (stack_.empty() || stack_.back().node != node) return false;
        out = stack_.back().costs;
        stack_.pop_back();
        return true;
    }

private:
    struct Entry {
        uint32_t node;
        Costs costs;
    };
    std::vector<Entry> stack_;
};

/// Pending costs in one array (any order with children after parents).
class CostArray {
public:
    explicit CostArray(size_t n) : costs_(n) {}
    void put(uint32_t node, const Costs& c) { costs_[node] = c; }
    bool take(uint32_t node, Costs& out) {
        out = costs_[node];
        return true;
    }

private:
    std::vector<Costs> costs_;
};

/// Cost store for the top of a parallel sweep: the few nodes above the task
/// subtrees, and the task subtrees' roots (sorted by node, looked up by
/// binary search; a handful of entries per task).
class CostMap {
public:
    void put(uint32_t node, const Costs& c) {
        auto it = std::lower_bound(entries_.begin(), entries_.end(), node,
                                   [](const Entry& e, uint32_t k) { return e.node < k; });
        entries_.insert(it, Entry{node, c});
    }
    bool take(uint32_t node, Costs& out) const {
        auto it = std::lower_bound(entries_.begin(), entries_.end(), node,
                                   [](const Entry& e, uint32_t k) { return e.node < k; });
        if (it == entries_.end() || it->node != node) return false;
        out = it->costs;
        return true;
    }

private:
    struct Entry {
        uint32_t node;
        Costs costs;
    };
    std::vector<Entry> entries_;
};

/// One node of the DP: reads its children's costs from `store` (false if the
/// store cannot serve them) and puts its own. Depends only on the node and
/// its children's costs: any schedule gives the same decisions.
template <class Store>
bool dp_node(const BinaryBvh& binary, const CollapseConfig& config, const std::vector<uint32_t>& ref_count,
             size_t idx, Store& store, std::vector<Decision>& dec) {
    const double c_node = config.cost_node, c_prim = config.cost_prim;
    const double inf = std::numeric_limits<double>::infinity();
    const BinaryNode& b = binary.nodes[idx];
    Costs out;
    const double area = b.box.half_area();
    const double leaf_cost = ref_count[idx] <= uint32_t(config.max_leaf)
                                 ? c_prim * distinct_leaf_triangles(binary, uint32_t(idx)) * area
                                 : inf;
    if (b.is_leaf()) {
        for (int i = 0; i < kMaxRoots; ++i) out.c[i] = leaf_cost;
        dec[idx].bits = Decision::pack_as_leaf(true);  // every split 0: one root, the leaf itself
        store.put(uint32_t(idx), out);
        return true;
    }
    Costs l, r;  // in a reverse preorder sweep the left subtree finished last
    if (!store.take(b.child[0], l) || !store.take(b.child[1], r)) return false;
    double best_children = inf;
    int best_k = 1;
    for (int k = 1; k <= kMaxRoots; ++k) {  // left gets k roots, right 8 - k (both >= 1)
        const double c = l.c[k - 1] + r.c[kWidth - k - 1];
        if (c < best_children) {
            best_children = c;
            best_k = k;
        }
    }
    const double internal_cost = c_node * area + best_children;
    // Ties go to the leaf: same SAH, one node fewer.
    const bool as_leaf = leaf_cost <= internal_cost;
    uint32_t packed = Decision::pack_internal_split(best_k) | Decision::pack_as_leaf(as_leaf);  // split(1) = 0
    out.c[0] = as_leaf ? leaf_cost : internal_cost;
    for (int i = 2; i <= kMaxRoots; ++i) {
        double best = out.c[0];
        int split = 0;
        for (int k = 1; k < i; ++k) {
            const double c = l.c[k - 1] + r.c[i - k - 1];
            if (c < best) {
                best = c;
                split = k;
            }
        }
        out.c[i - 1] = best;
        packed |= Decision::pack_split(i, split);
    }
    dec[idx].bits = packed;
    store.put(uint32_t(idx), out);
    return true;
}

/// The DP sweep over nodes [begin, end) in reverse order with a given cost
/// store; false if the store cannot serve the order (CostStack on a range
/// that is not in preorder). Children have larger indices than parents
/// (checked): a reverse sweep is an iterative post-order, with no recursion
/// depth limit. `progress` advances by one per node swept, in batches; a
/// sweep that fails takes its count back (the fallback sweeps again).
template <class Store>
bool run_dp(const BinaryBvh& binary, const CollapseConfig& config, const std::vector<uint32_t>& ref_count,
            size_t begin, size_t end, Store& store, std::vector<Decision>& dec, Progress* progress) {
    ProgressBatch swept(progress);
    for (size_t idx = end; idx-- > begin;) {
        swept.add(1);
        if (!dp_node(binary, config, ref_count, idx, store, dec)) {
            swept.retract();
            return false;
        }
    }
    return true;
}

/// Subtrees of at most this many nodes are swept by one task each.
constexpr size_t kTaskNodes = 1 << 16;

/// The backtracking walks the top wide levels until this many independent
/// wide subtrees are found (or the tree ends), then builds them in parallel.
constexpr size_t kFrontierItems = 512;

/// The DP of a tree in depth-first preorder (what both builders write), in
/// parallel: a node's subtree is the index range [node, end) (the root's end
/// is the node count; the left child's range ends where the right child
/// starts), so the tree is cut top-down into task subtrees of at most
/// kTaskNodes nodes, swept in parallel with a CostStack each, and the few
/// nodes above them are swept last. False (nothing decided that matters) if
/// the tree is not in preorder: the caller falls back to one CostArray sweep.
bool run_dp_parallel(const BinaryBvh& binary, const CollapseConfig& config, const std::vector<uint32_t>& ref_count,
                     std::vector<Decision>& dec, Progress* progress) {
    std::vector<uint32_t> top;    // nodes above the tasks, in preorder
    std::vector<NodeRange> tasks;
    if (!preorder_cut(binary, kTaskNodes, top, tasks)) return false;
    std::vector<Costs> roots(tasks.size());
    std::atomic<bool> ok{true};
    tbb::parallel_for(size_t(0), tasks.size(), [&](size_t t) {
        CostStack stack;
        if (!run_dp(binary, config, ref_count, tasks[t].begin, tasks[t].end, stack, dec, progress) ||
            !stack.take(tasks[t].begin, roots[t]) || !stack.empty())
            ok.store(false, std::memory_order_relaxed);
    });
    if (!ok.load()) return false;
    CostMap map;
    for (size_t t = 0; t < tasks.size(); ++t) map.put(tasks[t].begin, roots[t]);
    ProgressBatch swept(progress);
    for (size_t i = top.size(); i-- > 0;) {  // reverse preorder: children before parents
        swept.add(1);
        if (!dp_node(binary, config, ref_count, top[i], map, dec)) return false;
    }
    return true;
}

/// The roots of the optimal forests of internal binary node n's two children
/// (left gets internal_split roots, right the rest), left first; returns how
/// many (2..8). These become the children of the wide node made from n.
int wide_roots(const BinaryBvh& binary, const std::vector<Decision>& dp, uint32_t n, uint32_t* roots) {
    int count = 0;
    // expand(m, i): the roots of m's optimal forest of at most i roots.
    // Depth <= 7 (every split hands >= 1 root to each side).
    auto expand = [&](auto&& self, uint32_t m, int i) -> void {
        const int s = dp[m].split(i);
        if (s == 0) {
            roots[count++] = m;
            return;
        }
        self(self, binary.nodes[m].child[0], s);
        self(self, binary.nodes[m].child[1], i - s);
    };
    const int k = dp[n].internal_split();
    expand(expand, binary.nodes[n].child[0], k);
    expand(expand, binary.nodes[n].child[1], kWidth - k);
    assert(count >= 2 && count <= kWidth);
    return count;
}

}  // namespace

Result collapse_optimal(const BinaryBvh& binary, const CollapseConfig& config, std::vector<uint32_t> ref_count,
                        WideBvh& out, Progress* progress) {
    std::vector<Decision> dp(binary.nodes.size());
    if (!run_dp_parallel(binary, config, ref_count, dp, progress)) {
        // Not in preorder (or a subtree was not): one sweep over any valid order.
        if (progress) progress->reset(binary.nodes.size());
        CostArray array(binary.nodes.size());
        run_dp(binary, config, ref_count, 0, binary.nodes.size(), array, dp, progress);
    }
    std::vector<uint32_t>().swap(ref_count);  // not needed below: free it before the wide nodes exist

    // Backtracking: create wide nodes top-down. Each wide node gets the roots
    // of its binary node's two child forests. The top levels are walked
    // breadth first until there are enough independent wide subtrees (the
    // frontier); each frontier subtree is counted (wide nodes, leaf_refs
    // entries) in parallel, the arrays are allocated once at their exact
    // sizes (no regrowth: old and new arrays alive together), and every subtree is built
    // in parallel into its own ranges (offsets by prefix sums in frontier
    // order), so the result does not depend on the schedule.
    out.nodes.emplace_back();
    out.nodes[0].bnode = 0;
    if (binary.nodes[0].is_leaf()) {
        // Root forced internal: one wide leaf child holding the single reference.
        out.nodes[0].slots[0] = make_wide_leaf(binary, 0, out);
        return Result::success();
    }

    // Top levels: wide internal roots (binary node ids), breadth first.
    std::vector<uint32_t> top, frontier{0};
    uint32_t roots[kWidth];
    while (!frontier.empty() && frontier.size() < kFrontierItems) {
        std::vector<uint32_t> next;
        for (const uint32_t m : frontier) {
            top.push_back(m);
            const int count = wide_roots(binary, dp, m, roots);
            for (int c = 0; c < count; ++c)
                if (!dp[roots[c]].as_leaf()) next.push_back(roots[c]);
        }
        frontier.swap(next);
    }
    // Per frontier subtree: wide nodes and leaf_refs entries.
    struct Span {
        uint64_t nodes = 0, refs = 0;
    };
    std::vector<Span> span(frontier.size() + 1);
    tbb::parallel_for(size_t(0), frontier.size(), [&](size_t f) {
        Span s;
        std::vector<uint32_t> pending{frontier[f]};
        uint32_t r[kWidth];
        while (!pending.empty()) {
            const uint32_t m = pending.back();
            pending.pop_back();
            ++s.nodes;
            const int count = wide_roots(binary, dp, m, r);
            for (int c = 0; c < count; ++c) {
                if (dp[r[c]].as_leaf()) s.refs += distinct_leaf_triangles(binary, r[c]);
                else pending.push_back(r[c]);
            }
        }
        span[f + 1] = s;
    });
    uint64_t top_refs = 0;
    for (const uint32_t m : top) {
        const int count = wide_roots(binary, dp, m, roots);
        for (int c = 0; c < count; ++c)
            if (dp[roots[c]].as_leaf()) top_refs += distinct_leaf_triangles(binary, roots[c]);
    }
    // Prefix sums: subtree f's nodes start at span[f].nodes, its entries at span[f].refs.
    span[0] = {top.size(), top_refs};
    for (size_t f = 1; f < span.size(); ++f) {
        span[f].nodes += span[f - 1].nodes;
        span[f].refs += span[f - 1].refs;
    }
    const uint64_t total_nodes = span.back().nodes, total_refs = span.back().refs;
    if (total_nodes >= uint64_t(kInvalidIndex) || total_refs >= uint64_t(kInvalidIndex)) {
        return Result::fail(Status::kInvalidArgument, 0, "collapse: too many wide nodes");
    }
    out.nodes.resize(size_t(total_nodes));
    out.leaf_refs.resize(size_t(total_refs));

    // Top nodes: wide node t is top[t]; breadth first, so the internal
    // children met in order are top[1], top[2], ... then the frontier roots.
    {
        uint32_t ref_cursor = 0;
        size_t next = 1;
        for (size_t t = 0; t < top.size(); ++t) {
            const int count = wide_roots(binary, dp, top[t], roots);
            for (int c = 0; c < count; ++c) {
                const uint32_t m = roots[c];
                if (dp[m].as_leaf()) {
                    out.nodes[t].slots[c] = make_wide_leaf_at(binary, m, out, ref_cursor);
                    continue;
                }
                const size_t k = next++;
                const uint64_t child = k < top.size() ? k : span[k - top.size()].nodes;
                link_internal_child(m, uint32_t(t), c, uint32_t(child), out);
            }
        }
        assert(next == top.size() + frontier.size());
        assert(ref_cursor == top_refs);
    }
    struct Work {
        uint32_t binary;
        uint32_t wide;
    };
    tbb::parallel_for(size_t(0), frontier.size(), [&](size_t f) {
        uint32_t node_cursor = uint32_t(span[f].nodes);
        uint32_t ref_cursor = uint32_t(span[f].refs);
        std::vector<Work> work{{frontier[f], node_cursor++}};
        uint32_t r[kWidth];
        while (!work.empty()) {
            const Work w = work.back();
            work.pop_back();
            const int count = wide_roots(binary, dp, w.binary, r);
            uint32_t triangles = 0;
            for (int c = 0; c < count; ++c) {
                const uint32_t m = r[c];
                if (dp[m].as_leaf()) {
                    out.nodes[w.wide].slots[c] = make_wide_leaf_at(binary, m, out, ref_cursor);
                    triangles += out.nodes[w.wide].slots[c].ref_count;
                } else {
                    const uint32_t child = node_cursor++;
                    link_internal_child(m, w.wide, c, child, out);
                    work.push_back({m, child});
                }
            }
            // 8 leaves of <= 3 triangles: the 5-bit offsets always suffice.
            assert(triangles <= uint32_t(kMaxNodeTriangles));
            (void)triangles;
        }
        assert(node_cursor == span[f + 1].nodes && ref_cursor == span[f + 1].refs);
    });
    return Result::success();
}

}  // namespace cwbvh::compiler::detail
