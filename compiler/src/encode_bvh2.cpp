// BVH2 section: the binary SBVH in the 64-byte node layout of Aila & Laine's
// GPU kernels (Aila, Laine 2009; Aila, Laine, Karras 2012), sharing the TRIS
// records of the wide tree.
#include <climits>

#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/encode.h"

namespace cwbvh::compiler {

bool encode_bvh2(const BinaryBvh& binary, const WideBvh& wide, const EncodedTree& tree, std::vector<Bvh2Node>& out,
                 std::string& error) {
    out.clear();
    std::vector<uint32_t> ref_count;
    if (!detail::check_binary(binary, ref_count, error)) return false;
    if (wide.binary_leaf_ref.size() != binary.nodes.size()) {
        error = "bvh2: the wide BVH was not collapsed from this binary BVH";
        return false;
    }
    auto leaf_child = [&](uint32_t leaf, int32_t& child) {
        const uint32_t ref = wide.binary_leaf_ref[leaf];
        if (ref >= tree.ref_to_tri.size() || tree.ref_to_tri[ref] > uint32_t(INT32_MAX)) {
            error = "bvh2: binary leaf " + std::to_string(leaf) + " has no triangle record";
            return false;
        }
        child = ~int32_t(tree.ref_to_tri[ref]);
        return true;
    };
    auto set_box = [](Bvh2Node& n, int c, const Aabb& b) {
        if (c == 0) {
            n.c0_lo_x = b.lo[0], n.c0_hi_x = b.hi[0], n.c0_lo_y = b.lo[1], n.c0_hi_y = b.hi[1];
            n.c0_lo_z = b.lo[2], n.c0_hi_z = b.hi[2];
        } else {
            n.c1_lo_x = b.lo[0], n.c1_hi_x = b.hi[0], n.c1_lo_y = b.lo[1], n.c1_hi_y = b.hi[1];
            n.c1_lo_z = b.lo[2], n.c1_hi_z = b.hi[2];
        }
    };
    if (binary.nodes[0].is_leaf()) {
        // The kernels start at an internal node: duplicate the single leaf.
        Bvh2Node n{};
        int32_t child = 0;
        if (!leaf_child(0, child)) return false;
        set_box(n, 0, binary.nodes[0].box);
        set_box(n, 1, binary.nodes[0].box);
        n.child[0] = n.child[1] = child;
        out.push_back(n);
        return true;
    }
    // Internal binary nodes keep their (depth-first) order.
    std::vector<uint32_t> index(binary.nodes.size(), kInvalidIndex);
    uint32_t count = 0;
    for (size_t i = 0; i < binary.nodes.size(); ++i) {
        if (binary.nodes[i].is_leaf()) continue;
        if (count == uint32_t(INT32_MAX)) {
            error = "bvh2: too many nodes for 31-bit indices";
            return false;
        }
        index[i] = count++;
    }
    out.resize(count);
    for (size_t i = 0; i < binary.nodes.size(); ++i) {
        const BinaryNode& b = binary.nodes[i];
        if (b.is_leaf()) continue;
        Bvh2Node& n = out[index[i]];
        for (int c = 0; c < 2; ++c) {
            const uint32_t ch = b.child[c];
            set_box(n, c, binary.nodes[ch].box);
            if (binary.nodes[ch].is_leaf()) {
                if (!leaf_child(ch, n.child[c])) return false;
            } else {
                n.child[c] = int32_t(index[ch]);
            }
        }
    }
    return true;
}

}  // namespace cwbvh::compiler
