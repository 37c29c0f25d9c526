// WideBvh -> the NODE / TRIS / BV2L (or BVH2) sections of a .cwbvh file.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/compiler/model.h"
#include "cwbvh/format/format.h"

namespace cwbvh::compiler {

struct EncodedTree {
    std::vector<CwbvhNode> nodes;           ///< NODE, node 0 = root
    std::vector<TriangleRecord> triangles;  ///< TRIS, leaf order
    std::vector<Bvh2Node> bvh2;             ///< BV2L or BVH2 (filled by encode_bvh2, optional)
    /// WideBvh::leaf_refs index -> TRIS index.
    std::vector<uint32_t> ref_to_tri;
    /// NODE index -> WideBvh::nodes index.
    std::vector<uint32_t> node_to_wide;
    double avg_children = 0;
    uint32_t max_leaf_triangles = 0;
    double sah_wide = 0;                    ///< sah_cost_wide(wide, c_node, c_prim)
    uint64_t records = 0;                   ///< TRIS records laid out (triangles.size() once filled)
};

/// Layout (deterministic): depth first with contiguous sibling blocks. When a
/// node is visited, its internal children get consecutive NODE indices (in
/// slot order) at the end of NODE and the triangles of its leaf children get
/// consecutive TRIS records (in slot order) at the end of TRIS; its children
/// are then visited in slot order. So node 0 is the root, every child has a
/// larger index than its parent, siblings are adjacent and a subtree's nodes
/// are close together. Unused bases are 0 (child_base when imask == 0,
/// tri_base when the node has no leaf child).
/// c_node/c_prim only feed EncodedTree::sah_wide.
Result encode_cwbvh(const WideBvh& wide, const Scene& scene, EncodedTree& out,
                                float c_node = 1.0f, float c_prim = 0.3f);

/// encode_cwbvh in two steps, so that the binary tree (the exact boxes) can be
/// freed before the triangle records are allocated: the nodes (layout,
/// quantization, avg_children, sah_wide: reads the boxes), then the TRIS
/// records and ref_to_tri (reads no box). A tree failing in both steps
/// reports the node step's failure (encode_cwbvh: the leaves' first).
Result encode_cwbvh_nodes(const WideBvh& wide, EncodedTree& out, float c_node = 1.0f, float c_prim = 0.3f);
Result encode_cwbvh_triangles(const WideBvh& wide, const Scene& scene, EncodedTree& out);

/// The leaf order of an encoded tree for any primitive kind (triangles, or
/// the instances of a two-level scene's top level): after encode_cwbvh_nodes,
/// order[record] = the primitive id (WideBvh::leaf_refs value) that record
/// `record` of the leaf layout holds (the TRIS order; for a top level the INST
/// order). Each reference in exactly one record, else an error.
Result encode_leaf_order(const WideBvh& wide, const EncodedTree& tree, std::vector<uint32_t>& order);

/// BV2L section (binary BVH with leaf ranges, spec 3.6): Aila–Laine 64-byte nodes
/// over the binary BVH cut at the wide tree's leaves. Every wide leaf is one
/// binary subtree (the collapse made it from all binary leaves under one node m);
/// the BVH2 keeps the binary internal nodes above those subtrees (same order as
/// BinaryBvh::nodes, i.e. depth first), and the child that was m is a leaf child
/// with m's box, ~child = the wide leaf's first TRIS record and leaf_count = its
/// 1..3 records, so leaves share TRIS with the wide tree and no triangle is
/// duplicated. A tree that is a single wide leaf (one reference) gives one node
/// with that leaf in both children. Errors: a wide tree not collapsed from this
/// binary tree, a wide leaf whose records are not consecutive in TRIS, more than
/// 2^29 records (kMaxBvh2LeafTris).
/// leaf_ranges = false gives the BVH2 section instead (format 1.0, spec 3.6): the
/// whole binary tree in the same node order, every binary leaf a leaf child with
/// ~child = the TRIS record of its reference and leaf_count 0.
Result encode_bvh2(const BinaryBvh& binary, const WideBvh& wide, const EncodedTree& tree,
                               std::vector<Bvh2Node>& out, bool leaf_ranges = true);

/// Self-check: decodes every node and checks that every child's decoded box
/// contains its exact WideChild box, that meta/imask/bases/indices are
/// consistent and in range, every node is reached exactly once from the root,
/// every TRIS record is referenced exactly once and matches the scene, and
/// every stored triangle of the scene appears in at least one leaf.
/// `part` checks one side only (the node structure is checked by both): kBoxes
/// the containment (needs the boxes, not the records), kRecords the TRIS
/// records and coverage (needs no box).
enum class VerifyPart { kAll, kBoxes, kRecords };
Result verify_encoded(const EncodedTree& tree, const WideBvh& wide, const Scene& scene,
                      VerifyPart part = VerifyPart::kAll);

}  // namespace cwbvh::compiler
