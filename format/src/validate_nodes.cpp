// NODE and TLAS content rules (spec: "NODE", rules 51xx; TLAS, 61xx and 6041): one
// tree check over a node range and a leaf-record range serves the single-level tree,
// each bottom level of a two-level file, and the top level.
#include "cwbvh/format/tree_depth.h"
#include <algorithm>
#include <cmath>
#include <vector>

#include "cwbvh/format/hex.h"
#include "cwbvh/format/node_decode.h"
#include "validate_internal.h"

namespace cwbvh::detail {
namespace {

using std::to_string;

/// Where errors of one tree are reported: the section, a mesh label, and the rule offset
/// (0 for NODE, rule::kTlasRuleOffset for TLAS).
struct TreeNames {
    const char* section;       ///< "NODE" or "TLAS"
    const char* leaf_section;  ///< "TRIS" or "INST"
    std::string label;         ///< "" or "mesh 3: "
    uint32_t rule_offset;
};

Result node_error(const TreeNames& t, uint32_t rule_id, uint64_t node, const std::string& what) {
    return fail(rule_id + t.rule_offset,
                std::string("section ") + t.section + ": " + t.label + "node " + to_string(node) + ": " + what);
}
Result slot_error(const TreeNames& t, uint32_t rule_id, uint64_t node, int slot, const std::string& what) {
    return node_error(t, rule_id, node, "slot " + to_string(slot) + ": " + what);
}

/// Checks one slot; adds a leaf's triangles to `leaf_bits` and `leaf_total`.
Result check_slot(const TreeNames& t, const CwbvhNode& n, uint64_t i, int s, uint32_t& leaf_bits, int& leaf_total) {
    const uint8_t m = n.meta[s];
    const bool internal_bit = (n.imask >> s) & 1u;
    if (meta_is_empty(m)) {
        if (internal_bit) return slot_error(t, rule::kNodeImask, i, s, "imask bit set for an empty slot");
        for (int a = 0; a < 3; ++a)
            if (n.q_lo[a][s] != 0 || n.q_hi[a][s] != 0)
                return slot_error(t, rule::kNodeEmptySlot, i, s, "empty slot has non-zero plane bytes");
        return Result::success();
    }
    if ((m & 0x1F) >= 24) {
        if (m != make_meta_internal(s))
            return slot_error(t, rule::kNodeMeta, i, s, "meta " + hex8(m) + " is not the internal meta " +
                                                            hex8(make_meta_internal(s)) + " of this slot");
        if (!internal_bit) return slot_error(t, rule::kNodeImask, i, s, "internal meta but imask bit clear");
    } else {
        const int count = meta_leaf_count(m);
        const int offset = meta_leaf_offset(m);
        if (count == 0)
            return slot_error(t, rule::kNodeMeta, i, s, "meta " + hex8(m) + " has no valid unary count");
        if (offset + count > kMaxNodeTriangles)
            return slot_error(t, rule::kNodeMeta, i, s, "leaf entries " + to_string(offset) + "+" + to_string(count) +
                                                            " exceed the 24 of a node");
        if (internal_bit) return slot_error(t, rule::kNodeImask, i, s, "leaf meta but imask bit set");
        const uint32_t bits = ((1u << count) - 1u) << offset;
        if ((leaf_bits & bits) != 0)
            return slot_error(t, rule::kNodeLeafLayout, i, s, "leaf entries overlap another leaf of the node");
        leaf_bits |= bits;
        leaf_total += count;
    }
    for (int a = 0; a < 3; ++a) {
        if (n.q_lo[a][s] > n.q_hi[a][s])
            return slot_error(t, rule::kNodePlaneOrder, i, s, "q_lo > q_hi on axis " + to_string(a));
        const float lo = decode_plane(n.p[a], n.e[a], n.q_lo[a][s]);
        const float hi = decode_plane(n.p[a], n.e[a], n.q_hi[a][s]);
        if (!std::isfinite(lo) || !std::isfinite(hi))
            return slot_error(t, rule::kNodeNonFinite, i, s, "decoded child box is not finite on axis " + to_string(a));
    }
    return Result::success();
}

/// Per-element state of the tree checks, indexed absolutely (sized by the whole
/// sections, whose counts the structural rules bound by the file size).
struct TreeScratch {
    std::vector<uint8_t> parents;    ///< per node: has a parent
    std::vector<uint8_t> depth;      ///< per node: level, root = 1 (a parent precedes its children)
    std::vector<uint8_t> leaf_used;  ///< per leaf record: in a leaf
};

/// Rules 5101-5114 (+ t.rule_offset) on one tree: nodes [node_first, node_end) of `payload`,
/// root node_first, leaf records [leaf_first, leaf_end). Every index is absolute. `max_depth`
/// receives the tree's depth.
Result check_tree(const TreeNames& t, std::span<const uint8_t> payload, uint64_t node_first, uint64_t node_end,
                  uint64_t leaf_first, uint64_t leaf_end, TreeScratch& sc, uint32_t& max_depth) {
    max_depth = 1;
    sc.depth[node_first] = 1;
    for (uint64_t i = node_first; i < node_end; ++i) {
        const auto n = load<CwbvhNode>(payload, i);
        bool used = false;
        for (uint8_t m : n.meta) used |= m != kMetaEmpty;
        if (used) {
            for (int a = 0; a < 3; ++a) {
                if (n.e[a] < 1 || n.e[a] > 254)
                    return node_error(t, rule::kNodeExponent, i, "exponent byte " + to_string(n.e[a]) + " on axis " +
                                                                  to_string(a) + " is outside 1..254");
                if (!std::isfinite(n.p[a])) return node_error(t, rule::kNodeNonFinite, i, "origin p is not finite");
            }
        } else if (n.imask != 0) {
            return node_error(t, rule::kNodeImask, i, "imask set but every slot is empty");
        } else if (i != node_first) {
            // Spec 3.1 item 1: only the root of an empty scene may have no used slot.
            return node_error(t, rule::kNodeEmpty, i, "has no used slot (only the root of an empty scene may)");
        }
        uint32_t leaf_bits = 0;
        int leaf_total = 0;
        for (int s = 0; s < kWidth; ++s)
            if (Result r = check_slot(t, n, i, s, leaf_bits, leaf_total); !r.ok()) return r;
        if (leaf_bits != (1u << leaf_total) - 1u)
            return node_error(t, rule::kNodeLeafLayout, i, std::string("leaf entries are not contiguous from tri_base"));
        if (leaf_total > 0) {
            if (n.tri_base < leaf_first || uint64_t(n.tri_base) + uint64_t(leaf_total) > leaf_end)
                return node_error(t, rule::kNodeLeafRange, i, std::string("leaf ") + t.leaf_section + " records " +
                                                                  to_string(n.tri_base) + "+" + to_string(leaf_total) +
                                                                  " are not inside " + t.leaf_section + " " +
                                                                  to_string(leaf_first) + ".." + to_string(leaf_end));
            for (int k = 0; k < leaf_total; ++k) {
                if (sc.leaf_used[n.tri_base + k] != 0)
                    return node_error(t, rule::kNodeTriangleUse, i, std::string(t.leaf_section) + " record " +
                                                                        to_string(n.tri_base + k) +
                                                                        " is referenced by more than one leaf");
                sc.leaf_used[n.tri_base + k] = 1;
            }
        }
        const int internal = __builtin_popcount(n.imask);
        if (internal == 0) continue;
        if (n.child_base <= i)
            return node_error(t, rule::kNodeChildOrder, i, "child_base " + to_string(n.child_base) +
                                                               " is not greater than the node's index");
        if (uint64_t(n.child_base) + uint64_t(internal) > node_end)
            return node_error(t, rule::kNodeChildRange, i, "children " + to_string(n.child_base) + "+" +
                                                               to_string(internal) + " are not inside " + t.section +
                                                               " " + to_string(node_first) + ".." + to_string(node_end));
        for (int c = 0; c < internal; ++c) {
            const uint64_t child = uint64_t(n.child_base) + uint64_t(c);
            if (sc.parents[child] != 0)
                return node_error(t, rule::kNodeParents, i, "child node " + to_string(child) + " already has a parent");
            sc.parents[child] = 1;
            sc.depth[child] = uint8_t(sc.depth[i] + 1);
            if (sc.depth[child] > kMaxWideDepth)
                return node_error(t, rule::kNodeDepth, child, "is at depth " + to_string(sc.depth[child]) +
                                                                  "; the tree may be at most " +
                                                                  to_string(kMaxWideDepth) + " levels deep");
            max_depth = std::max<uint32_t>(max_depth, sc.depth[child]);
        }
    }
    for (uint64_t j = node_first + 1; j < node_end; ++j)
        if (sc.parents[j] == 0) return node_error(t, rule::kNodeParents, j, "is not the child of any node");
    for (uint64_t r = leaf_first; r < leaf_end; ++r)
        if (sc.leaf_used[r] == 0)
            return fail(rule::kNodeTriangleUse + t.rule_offset, std::string("section ") + t.section + ": " + t.label +
                                                                    t.leaf_section + " record " + to_string(r) +
                                                                    " is not in any leaf");
    return Result::success();
}

TreeScratch make_scratch(uint64_t nodes, uint64_t leaves) {
    TreeScratch sc;
    sc.parents.assign(nodes, 0);
    sc.depth.assign(nodes, 1);
    sc.leaf_used.assign(leaves, 0);
    return sc;
}

/// Levels of the tree of nodes [first, end) rooted at `first`, following only children
/// inside the range after their parent: bounded and safe on any bytes (exact on a valid tree).
uint32_t safe_range_depth(std::span<const uint8_t> payload, uint64_t first, uint64_t end, std::vector<uint8_t>& depth) {
    uint32_t max_depth = 1;
    for (uint64_t i = first; i < end; ++i) depth[i] = 0;
    depth[first] = 1;
    for (uint64_t i = first; i < end; ++i) {
        if (depth[i] == 0) continue;
        const auto n = load<CwbvhNode>(payload, i);
        const int internal = __builtin_popcount(n.imask);
        for (int c = 0; c < internal; ++c) {
            const uint64_t child = uint64_t(n.child_base) + uint64_t(c);
            if (child <= i || child >= end) continue;
            const uint8_t d = uint8_t(std::min<uint32_t>(255u, depth[i] + 1u));
            depth[child] = std::max(depth[child], d);
            max_depth = std::max<uint32_t>(max_depth, d);
        }
    }
    return max_depth;
}

}  // namespace

Result check_nodes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    const uint64_t tri_count = count_of(layout, kSectionTriangles);
    TreeScratch sc = make_scratch(count, tri_count);
    uint32_t depth = 0;
    if (layout.find(kSectionMeshes) == nullptr)
        return check_tree(TreeNames{"NODE", "TRIS", "", 0}, payload, 0, count, 0, tri_count, sc, depth);
    // Two-level (spec 3.9): one tree per mesh range; the ranges must be sound first.
    std::vector<MeshRecord> meshes;
    if (Result r = load_mesh_ranges(layout, meshes); !r.ok()) return r;
    for (size_t m = 0; m < meshes.size(); ++m) {
        const MeshRecord& mr = meshes[m];
        const TreeNames names{"NODE", "TRIS", "mesh " + to_string(m) + ": ", 0};
        if (Result r = check_tree(names, payload, mr.node_first, uint64_t(mr.node_first) + mr.node_count,
                                  mr.tri_first, uint64_t(mr.tri_first) + mr.tri_count, sc, depth);
            !r.ok())
            return r;
    }
    return Result::success();
}

Result check_top_nodes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    const uint64_t inst_count = count_of(layout, kSectionInstances);
    TreeScratch sc = make_scratch(count, inst_count);
    uint32_t depth = 0;
    const TreeNames names{"TLAS", "INST", "", rule::kTlasRuleOffset};
    if (Result r = check_tree(names, payload, 0, count, 0, inst_count, sc, depth); !r.ok()) return r;

    // Rule 6041: TLAS level of the node holding an instance + its mesh's depth <= 32.
    std::vector<MeshRecord> meshes;
    if (Result r = load_mesh_ranges(layout, meshes); !r.ok()) return r;
    const SectionEntry* node_entry = layout.find(kSectionNodes);
    const std::span<const uint8_t> nodes = layout.payload(*node_entry);
    std::vector<uint8_t> scratch_depth(node_entry->element_count, 0);
    std::vector<uint32_t> mesh_depth(meshes.size());
    for (size_t m = 0; m < meshes.size(); ++m)
        mesh_depth[m] = safe_range_depth(nodes, meshes[m].node_first,
                                         uint64_t(meshes[m].node_first) + meshes[m].node_count, scratch_depth);
    const std::span<const uint8_t> inst = layout.payload(*layout.find(kSectionInstances));
    for (uint64_t i = 0; i < count; ++i) {
        const auto n = load<CwbvhNode>(payload, i);
        for (int s = 0; s < kWidth; ++s) {
            const uint8_t m = n.meta[s];
            if (meta_is_empty(m) || meta_is_internal(m)) continue;
            for (int k = 0; k < meta_leaf_count(m); ++k) {
                const uint64_t j = uint64_t(n.tri_base) + uint64_t(meta_leaf_offset(m)) + uint64_t(k);
                const auto rec = load<InstanceRecord>(inst, j);
                if (rec.mesh >= meshes.size())
                    return fail(rule::kInstMesh, "section INST: instance " + to_string(j) + ": mesh " +
                                                     to_string(rec.mesh) + " is not below MESH count " +
                                                     to_string(meshes.size()));
                if (sc.depth[i] + mesh_depth[rec.mesh] > kMaxWideDepth)
                    return fail(rule::kTwoLevelDepth,
                                "section TLAS: node " + to_string(i) + ": instance " + to_string(j) + " of mesh " +
                                    to_string(rec.mesh) + " is at TLAS level " + to_string(sc.depth[i]) +
                                    " and the mesh is " + to_string(mesh_depth[rec.mesh]) + " levels deep; together " +
                                    "at most " + to_string(kMaxWideDepth));
            }
        }
    }
    return Result::success();
}

}  // namespace cwbvh::detail
