// NODE content rules (spec: "NODE", rules 51xx).
#include "cwbvh/format/tree_depth.h"
#include <cmath>
#include <vector>

#include "cwbvh/format/node_decode.h"
#include "validate_internal.h"

namespace cwbvh::detail {
namespace {

using std::to_string;

Result node_error(uint32_t rule_id, uint64_t node, const std::string& what) {
    return fail(rule_id, "section NODE: node " + to_string(node) + ": " + what);
}
Result slot_error(uint32_t rule_id, uint64_t node, int slot, const std::string& what) {
    return node_error(rule_id, node, "slot " + to_string(slot) + ": " + what);
}

/// Checks one slot; adds a leaf's triangles to `leaf_bits` and `leaf_total`.
Result check_slot(const CwbvhNode& n, uint64_t i, int s, uint32_t& leaf_bits, int& leaf_total) {
    const uint8_t m = n.meta[s];
    const bool internal_bit = (n.imask >> s) & 1u;
    if (meta_is_empty(m)) {
        if (internal_bit) return slot_error(rule::kNodeImask, i, s, "imask bit set for an empty slot");
        for (int a = 0; a < 3; ++a)
            if (n.q_lo[a][s] != 0 || n.q_hi[a][s] != 0)
                return slot_error(rule::kNodeEmptySlot, i, s, "empty slot has non-zero plane bytes");
        return Result::success();
    }
    if ((m & 0x1F) >= 24) {
        if (m != make_meta_internal(s))
            return slot_error(rule::kNodeMeta, i, s, "meta " + hex_byte(m) + " is not the internal meta " +
                                                         hex_byte(make_meta_internal(s)) + " of this slot");
        if (!internal_bit) return slot_error(rule::kNodeImask, i, s, "internal meta but imask bit clear");
    } else {
        const int count = meta_leaf_count(m);
        const int offset = meta_leaf_offset(m);
        if (count == 0)
            return slot_error(rule::kNodeMeta, i, s, "meta " + hex_byte(m) + " has no valid unary triangle count");
        if (offset + count > kMaxNodeTriangles)
            return slot_error(rule::kNodeMeta, i, s, "leaf triangles " + to_string(offset) + "+" + to_string(count) +
                                                         " exceed the 24 of a node");
        if (internal_bit) return slot_error(rule::kNodeImask, i, s, "leaf meta but imask bit set");
        const uint32_t bits = ((1u << count) - 1u) << offset;
        if ((leaf_bits & bits) != 0)
            return slot_error(rule::kNodeLeafLayout, i, s, "leaf triangles overlap another leaf of the node");
        leaf_bits |= bits;
        leaf_total += count;
    }
    for (int a = 0; a < 3; ++a) {
        if (n.q_lo[a][s] > n.q_hi[a][s])
            return slot_error(rule::kNodePlaneOrder, i, s, "q_lo > q_hi on axis " + to_string(a));
        const float lo = decode_plane(n.p[a], n.e[a], n.q_lo[a][s]);
        const float hi = decode_plane(n.p[a], n.e[a], n.q_hi[a][s]);
        if (!std::isfinite(lo) || !std::isfinite(hi))
            return slot_error(rule::kNodeNonFinite, i, s, "decoded child box is not finite on axis " + to_string(a));
    }
    return Result::success();
}

}  // namespace

Result check_nodes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    const uint64_t tri_count = count_of(layout, kSectionTriangles);
    std::vector<uint8_t> parents(count, 0);    // saturates at 2
    std::vector<uint8_t> depth(count, 1);      // root = 1; a parent precedes its children
    std::vector<uint8_t> tri_used(tri_count, 0);
    for (uint64_t i = 0; i < count; ++i) {
        const auto n = load<CwbvhNode>(payload, i);
        bool used = false;
        for (uint8_t m : n.meta) used |= m != kMetaEmpty;
        if (used) {
            for (int a = 0; a < 3; ++a) {
                if (n.e[a] < 1 || n.e[a] > 254)
                    return node_error(rule::kNodeExponent, i, "exponent byte " + to_string(n.e[a]) + " on axis " +
                                                               to_string(a) + " is outside 1..254");
                if (!std::isfinite(n.p[a])) return node_error(rule::kNodeNonFinite, i, "origin p is not finite");
            }
        } else if (n.imask != 0) {
            return node_error(rule::kNodeImask, i, "imask set but every slot is empty");
        } else if (i != 0) {
            // Spec 3.1 item 1: only the root of an empty scene may have no used slot.
            return node_error(rule::kNodeEmpty, i, "has no used slot (only the root of an empty scene may)");
        }
        uint32_t leaf_bits = 0;
        int leaf_total = 0;
        for (int s = 0; s < kWidth; ++s)
            if (Result r = check_slot(n, i, s, leaf_bits, leaf_total); !r.ok()) return r;
        if (leaf_bits != (1u << leaf_total) - 1u)
            return node_error(rule::kNodeLeafLayout, i, "leaf triangles are not contiguous from tri_base");
        if (leaf_total > 0) {
            if (uint64_t(n.tri_base) + uint64_t(leaf_total) > tri_count)
                return node_error(rule::kNodeLeafRange, i, "leaf triangles " + to_string(n.tri_base) + "+" +
                                                               to_string(leaf_total) + " exceed TRIS count " +
                                                               to_string(tri_count));
            for (int t = 0; t < leaf_total; ++t) {
                if (tri_used[n.tri_base + t] != 0)
                    return node_error(rule::kNodeTriangleUse, i, "TRIS record " + to_string(n.tri_base + t) +
                                                                     " is referenced by more than one leaf");
                tri_used[n.tri_base + t] = 1;
            }
        }
        const int internal = __builtin_popcount(n.imask);
        if (internal == 0) continue;
        if (n.child_base <= i)
            return node_error(rule::kNodeChildOrder, i, "child_base " + to_string(n.child_base) +
                                                            " is not greater than the node's index");
        if (uint64_t(n.child_base) + uint64_t(internal) > count)
            return node_error(rule::kNodeChildRange, i, "children " + to_string(n.child_base) + "+" +
                                                            to_string(internal) + " exceed NODE count " +
                                                            to_string(count));
        for (int c = 0; c < internal; ++c) {
            uint8_t& p = parents[n.child_base + c];
            if (p != 0)
                return node_error(rule::kNodeParents, i, "child node " + to_string(n.child_base + c) +
                                                             " already has a parent");
            p = 1;
            depth[n.child_base + c] = uint8_t(depth[i] + 1);
            if (depth[n.child_base + c] > kMaxWideDepth)
                return node_error(rule::kNodeDepth, n.child_base + c, "is at depth " + to_string(depth[n.child_base + c]) +
                                                                         "; the tree may be at most " +
                                                                         to_string(kMaxWideDepth) + " levels deep");
        }
    }
    for (uint64_t j = 1; j < count; ++j)
        if (parents[j] == 0) return node_error(rule::kNodeParents, j, "is not the child of any node");
    for (uint64_t t = 0; t < tri_count; ++t)
        if (tri_used[t] == 0)
            return fail(rule::kNodeTriangleUse, "section NODE: TRIS record " + to_string(t) + " is not in any leaf");
    return Result::success();
}

}  // namespace cwbvh::detail
