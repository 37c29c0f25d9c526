// BV2L section: the binary SBVH in the 64-byte node layout of Aila & Laine's GPU
// kernels (Aila, Laine 2009; Aila, Laine, Karras 2012), cut at the wide tree's
// leaves so that a leaf holds the same 1-3 triangle records as the wide leaf
// (Ylitie et al. 2017's SAH-optimal collapse chose them), sharing TRIS.
//
// Each wide leaf was made from one binary subtree (collapse.cpp, make_wide_leaf:
// all binary leaves under the subtree's root m, duplicates of one triangle stored
// once), and the encoder put its records consecutively in TRIS. So the BVH2 keeps
// the binary nodes above those subtrees, and the child that was m becomes a leaf
// child: box = m's box (= the wide leaf's exact box), ~child = the first TRIS
// record, leaf_count = the record count. No triangle is duplicated.
//
// BVH2 section (format 1.0, one record per leaf): the whole binary tree, every
// binary leaf a leaf child holding the TRIS record of its reference
// (leaf_count 0). Binary leaves of one triangle that the collapse merged into
// one wide leaf share that record.
#include <climits>

#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/encode.h"

namespace cwbvh::compiler {
namespace {

struct Bvh2Leaf {
    uint32_t first_tri;  ///< first TRIS record
    uint32_t count;      ///< records, 1..kMaxBvh2LeafTriangles
    uint32_t cuts = 0;   ///< binary subtree roots found for it (must end at 1)
};

/// One entry per wide leaf; ref_leaf[r] = the wide leaf holding WideBvh::leaf_refs[r].
Result wide_leaves(const WideBvh& wide, const EncodedTree& tree, std::vector<Bvh2Leaf>& leaves,
                 std::vector<uint32_t>& ref_leaf) {
    ref_leaf.assign(wide.leaf_refs.size(), kInvalidIndex);
    for (const WideNode& node : wide.nodes) {
        for (const WideChild& ch : node.slots) {
            if (ch.kind != WideChild::kLeaf) continue;
            const uint32_t id = uint32_t(leaves.size());
            if (ch.ref_count < 1 || ch.ref_count > kMaxBvh2LeafTriangles || ch.first_ref > ref_leaf.size() ||
                ch.ref_count > ref_leaf.size() - ch.first_ref)
                return Result::fail(Status::kInvalidArgument, 0,
                                    "bvh2: wide leaf " + std::to_string(id) + " has a bad reference range");
            const uint32_t first =
                ch.first_ref < tree.ref_to_tri.size() ? tree.ref_to_tri[ch.first_ref] : kInvalidIndex;
            for (uint32_t k = 0; k < ch.ref_count; ++k) {
                const uint32_t r = ch.first_ref + k;
                // encode_cwbvh gives a leaf's triangles consecutive records (spec 3.1 layout).
                if (r >= tree.ref_to_tri.size() || first > uint32_t(INT32_MAX) - k || tree.ref_to_tri[r] != first + k) {
                    return Result::fail(
                        Status::kInvalidArgument, 0,
                        "bvh2: the records of wide leaf " + std::to_string(id) + " are not consecutive in TRIS");
                }
                if (ref_leaf[r] != kInvalidIndex) {
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "bvh2: reference " + std::to_string(r) + " is in two wide leaves");
                }
                ref_leaf[r] = id;
            }
            leaves.push_back({first, ch.ref_count});
        }
    }
    return Result::success();
}

void set_box(Bvh2Node& n, int c, const Aabb& b) {
    if (c == 0) {
        n.c0_lo_x = b.lo[0], n.c0_hi_x = b.hi[0], n.c0_lo_y = b.lo[1], n.c0_hi_y = b.hi[1];
        n.c0_lo_z = b.lo[2], n.c0_hi_z = b.hi[2];
    } else {
        n.c1_lo_x = b.lo[0], n.c1_hi_x = b.hi[0], n.c1_lo_y = b.lo[1], n.c1_hi_y = b.hi[1];
        n.c1_lo_z = b.lo[2], n.c1_hi_z = b.hi[2];
    }
}

}  // namespace

Result encode_bvh2(const BinaryBvh& binary, const WideBvh& wide, const EncodedTree& tree, std::vector<Bvh2Node>& out,
                   bool leaf_ranges) {
    out.clear();
    std::vector<uint32_t> ref_count;
    if (Result r = detail::check_binary(binary, ref_count); !r.ok()) return r;
    if (wide.binary_leaf_ref.size() != binary.nodes.size()) {
        return Result::fail(Status::kInvalidArgument, 0, "bvh2: the wide BVH was not collapsed from this binary BVH");
    }
    if (leaf_ranges ? tree.triangles.size() > kMaxBvh2LeafTris : tree.triangles.size() > size_t(INT32_MAX)) {
        return Result::fail(Status::kInvalidArgument, 0,
                            leaf_ranges ? "bvh2: more than 2^29 triangle records (the limit of the BV2L section)"
                                        : "bvh2: more than 2^31 - 1 triangle records (the limit of the BVH2 section)");
    }
    std::vector<Bvh2Leaf> leaves;
    std::vector<uint32_t> ref_leaf;
    if (Result r = wide_leaves(wide, tree, leaves, ref_leaf); !r.ok()) return r;

    // group[i]: the BVH2 leaf binary node i becomes, or kInvalidIndex if i stays an
    // internal BVH2 node (or lies below a leaf). BV2L: the wide leaf every binary
    // leaf under i belongs to, if they all belong to one. BVH2: one leaf per binary
    // leaf, holding that reference's record. Children have larger indices than
    // their parent (check_binary), so one backward pass.
    const size_t n_binary = binary.nodes.size();
    std::vector<uint32_t> group(n_binary, kInvalidIndex);
    if (!leaf_ranges) leaves.clear();
    for (size_t i = n_binary; i-- > 0;) {
        const BinaryNode& b = binary.nodes[i];
        if (b.is_leaf()) {
            const uint32_t r = wide.binary_leaf_ref[i];
            if (r >= ref_leaf.size() || ref_leaf[r] == kInvalidIndex) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "bvh2: binary leaf " + std::to_string(i) + " is in no wide leaf");
            }
            if (leaf_ranges) {
                group[i] = ref_leaf[r];
            } else {
                group[i] = uint32_t(leaves.size());
                leaves.push_back({tree.ref_to_tri[r], 1});
            }
        } else if (leaf_ranges && group[b.child[0]] == group[b.child[1]]) {
            group[i] = group[b.child[0]];
        }
    }
    // BVH2 (1.0) leaves hold one record and leave leaf_count 0 (spec 3.6).
    auto leaf_count = [&](const Bvh2Leaf& leaf) { return leaf_ranges ? leaf.count : 0u; };

    if (group[0] != kInvalidIndex) {
        // The whole tree is one leaf (a single reference): the kernels start at
        // an internal node, so the root holds that leaf in both children.
        Bvh2Leaf& leaf = leaves[group[0]];
        Bvh2Node n{};
        for (int c = 0; c < 2; ++c) {
            set_box(n, c, binary.nodes[0].box);
            n.child[c] = ~int32_t(leaf.first_tri);
            n.leaf_count[c] = leaf_count(leaf);
        }
        out.push_back(n);
        leaf.cuts = 1;
    } else {
        // Binary nodes above the cut keep their (depth-first) order.
        std::vector<uint32_t> index(n_binary, kInvalidIndex);
        uint32_t count = 0;
        for (size_t i = 0; i < n_binary; ++i) {
            if (group[i] != kInvalidIndex) continue;
            if (count == uint32_t(INT32_MAX)) {
                return Result::fail(Status::kInvalidArgument, 0, "bvh2: too many nodes for 31-bit indices");
            }
            index[i] = count++;
        }
        out.resize(count);
        for (size_t i = 0; i < n_binary; ++i) {
            if (index[i] == kInvalidIndex) continue;
            const BinaryNode& b = binary.nodes[i];
            Bvh2Node& n = out[index[i]];
            for (int c = 0; c < 2; ++c) {
                const uint32_t ch = b.child[c];
                set_box(n, c, binary.nodes[ch].box);
                if (group[ch] == kInvalidIndex) {
                    n.child[c] = int32_t(index[ch]);
                    n.leaf_count[c] = 0;
                    continue;
                }
                Bvh2Leaf& leaf = leaves[group[ch]];
                ++leaf.cuts;
                n.child[c] = ~int32_t(leaf.first_tri);
                n.leaf_count[c] = leaf_count(leaf);
            }
        }
    }
    for (size_t id = 0; id < leaves.size(); ++id) {
        if (leaves[id].cuts != 1) {
            return Result::fail(Status::kInvalidArgument, 0,
                                "bvh2: leaf " + std::to_string(id) + " is not one binary subtree");
        }
    }
    return Result::success();
}

}  // namespace cwbvh::compiler
