// Binary BVH -> 8-wide BVH (Ylitie, Karras, Laine 2017, "Efficient Incoherent
// Ray Traversal on GPUs Through Compressed Wide BVHs", section 3.1).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

struct Progress;

/// Collapses a binary BVH with one triangle reference per leaf into an 8-wide
/// BVH with <= config.max_leaf (<= 3) triangles per leaf. The root is always an
/// internal wide node (a one-triangle scene gives a root with one leaf child).
///   kCollapseOptimal: the SAH-optimal dynamic program of Ylitie et al. 2017.
///   kCollapseGreedy:  top-down collapse (Wald et al. 2008 / Afra et al. 2013
///                     style): open the child with the largest surface area
///                     until 8 children; a subtree with <= max_leaf references
///                     becomes a leaf.
/// Duplicate references of one triangle (spatial splits) that land in the same
/// wide leaf are stored once. Children occupy slots 0..k-1; call
/// assign_slots() to order them. Errors: malformed binary trees (bad child
/// index, shared or unreachable node, empty/non-finite box), bad config.
/// `progress` (optional) advances by one per binary node, by exactly
/// binary.nodes.size() when this returns true; it never influences the tree.
Result collapse_wide(const BinaryBvh& binary, const CollapseConfig& config, WideBvh& out, Progress* progress = nullptr);

/// SAH cost of a wide tree, normalised by the root's area (spec formula):
///   sum over internal nodes C_node * A(n) / A(root)
/// + sum over leaf children C_prim * count * A(leaf) / A(root)
/// A = surface area of the exact (unquantized) box. A root of zero area
/// (then every area is zero) gives 0.
double sah_cost_wide(const WideBvh& wide, float c_node, float c_prim);

/// Average number of non-empty slots per wide node.
double wide_avg_children(const WideBvh& wide);

namespace detail {
/// Checks the BinaryBvh invariants the collapse relies on (node 0 root, leaf
/// with a valid prim, children with larger indices, every non-root node has
/// exactly one parent, finite non-empty boxes) and counts the leaf references
/// under every node (saturating at UINT32_MAX).
Result check_binary(const BinaryBvh& binary, std::vector<uint32_t>& ref_count);

/// Appends a wide leaf made of the binary leaves under `node` (left first,
/// duplicates removed) to wide.leaf_refs and fills binary_leaf_ref
/// (make_wide_leaf_at after growing leaf_refs).
WideChild make_wide_leaf(const BinaryBvh& binary, uint32_t node, WideBvh& wide);

/// make_wide_leaf into wide.leaf_refs[cursor...] (already sized: as many
/// entries as distinct_leaf_triangles(binary, node)); advances `cursor`.
/// Leaves written by different threads must not share binary leaves or entries.
WideChild make_wide_leaf_at(const BinaryBvh& binary, uint32_t node, WideBvh& wide, uint32_t& cursor);

/// An index range of binary nodes [begin, end).
struct NodeRange {
    uint32_t begin, end;
};

/// Cuts a tree in depth-first preorder (a node's subtree is the index range
/// [node, end): the root's end is the node count, the left child's ends where
/// the right child starts) top-down into subtrees of at most `max_nodes`
/// nodes (`tasks`, disjoint ranges) and the nodes above them (`top`, parents
/// before children). False if a node above the cut is not in preorder.
bool preorder_cut(const BinaryBvh& binary, size_t max_nodes, std::vector<uint32_t>& top,
                  std::vector<NodeRange>& tasks);

/// Appends a wide node for binary node `binary_node` and makes it the internal
/// child in slot `slot` of wide node `parent`; `child` gets its index.
/// False (error set) when the wide node count would overflow 32 bits.
Result add_internal_child(uint32_t binary_node, uint32_t parent, int slot, WideBvh& out, uint32_t& child);

/// Makes existing wide node `child` (made from binary node `binary_node`) the
/// internal child in slot `slot` of wide node `parent`.
void link_internal_child(uint32_t binary_node, uint32_t parent, int slot, uint32_t child, WideBvh& out);

/// Number of distinct triangles among the binary leaves under `node`
/// (which must hold at most `limit` references; the answer is then <= limit).
uint32_t distinct_leaf_triangles(const BinaryBvh& binary, uint32_t node);

/// `ref_count` is taken over and released after the dynamic program (before the
/// wide nodes are allocated: it is not needed for them, and the peak memory of
/// the compile is here).
Result collapse_optimal(const BinaryBvh& binary, const CollapseConfig& config, std::vector<uint32_t> ref_count,
                        WideBvh& out, Progress* progress = nullptr);
Result collapse_greedy(const BinaryBvh& binary, const CollapseConfig& config,
                     const std::vector<uint32_t>& ref_count, WideBvh& out,
                     Progress* progress = nullptr);
}  // namespace detail

}  // namespace cwbvh::compiler
