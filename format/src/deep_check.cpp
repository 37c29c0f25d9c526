#include "cwbvh/format/deep_check.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/transform_host.h"

namespace cwbvh {
namespace {

struct Box {
    float lo[3], hi[3];
};

Box decoded_box(const CwbvhNode& n, int slot) {
    Box b;
    decode_slot_box(n, slot, b.lo, b.hi);
    return b;
}

bool contains(const Box& outer, const Box& inner) {
    for (int a = 0; a < 3; ++a)
        if (!(outer.lo[a] <= inner.lo[a] && inner.hi[a] <= outer.hi[a])) return false;
    return true;
}

Box triangle_bounds(const TriangleRecord& t) {
    Box b;
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::min({t.v0[a], t.v1[a], t.v2[a]});
        b.hi[a] = std::max({t.v0[a], t.v1[a], t.v2[a]});
    }
    return b;
}

bool overlaps(const Box& x, const Box& y) {
    for (int a = 0; a < 3; ++a)
        if (x.hi[a] < y.lo[a] || y.hi[a] < x.lo[a]) return false;
    return true;
}

/// Point (double) inside a float box, with a tolerance of 2^-40 of the magnitude:
/// lattice points are computed in double and may sit a few double ulps off the
/// triangle's plane, never a float ulp.
bool contains_point(const Box& b, const double p[3]) {
    for (int a = 0; a < 3; ++a) {
        const double tol = std::ldexp(std::max({std::fabs(p[a]), double(std::fabs(b.lo[a])),
                                                double(std::fabs(b.hi[a]))}), -40);
        if (!(double(b.lo[a]) - tol <= p[a] && p[a] <= double(b.hi[a]) + tol)) return false;
    }
    return true;
}

std::string box_text(const Box& b) {
    char s[200];
    std::snprintf(s, sizeof s, "[%.9g %.9g %.9g]-[%.9g %.9g %.9g]", b.lo[0], b.lo[1], b.lo[2], b.hi[0], b.hi[1],
                  b.hi[2]);
    return s;
}

struct LeafRef {
    uint32_t prim;
    uint32_t record;
    uint32_t node;  ///< the node holding the leaf slot
    uint8_t slot;
};

/// (parent node, slot in parent) of every node; a root (node 0, or a mesh's root in a
/// two-level file: spec 3.9) has none (node = kInvalidIndex).
struct Parent {
    uint32_t node = kInvalidIndex;
    uint8_t slot = 0;
};

/// The boxes from a leaf slot up to its tree's root's child slot: all the boxes a ray must
/// enter to reach that leaf (in a two-level file: up to the mesh's root). `box_of(node, slot)` gives a slot's box; `max_levels` bounds the walk (a
/// valid file is never deeper: rules 5113, 5606).
template <class BoxOf, class Pred>
bool chain_holds(const BoxOf& box_of, const std::vector<Parent>& parent, uint32_t node, int slot, int max_levels,
                 Pred&& inside) {
    for (int guard = 0; guard <= max_levels; ++guard) {
        if (!inside(box_of(node, slot))) return false;
        if (parent[node].node == kInvalidIndex) return true;
        slot = parent[node].slot;
        node = parent[node].node;
    }
    return false;  // deeper than any valid file
}

/// The names a tree's checks report under: D2/D3 for NODE, D6 (with the section) for BVH2/BV2L.
struct CheckNames {
    const char* contain;  ///< unsplit triangles inside their chain
    const char* cover;    ///< split triangles covered by their chains
    const char* what;     ///< "" or "BV2L: "
};

/// D2 and D3 (or D6) over every leaf reference of one tree: an unsplit triangle (one record)
/// lies with its exact bounds inside every box from its leaf to the root; every lattice point
/// of a split one lies inside the whole chain of one of its records.
template <class BoxOf>
Result check_geometry(std::span<const TriangleRecord> triangles, std::vector<LeafRef>& leaf_refs,
                      const std::vector<Parent>& parent, const BoxOf& box_of, int max_levels, const CheckNames& id,
                      DeepCheckStats& st) {
    auto fail_deep = [&](const char* check, const std::string& what) {
        return Result::fail(Status::kCorrupt, 0, std::string("deep check ") + check + ": " + id.what + what);
    };
    std::sort(leaf_refs.begin(), leaf_refs.end(),
              [](const LeafRef& x, const LeafRef& y) { return x.prim != y.prim ? x.prim < y.prim : x.record < y.record; });
    for (size_t i = 0; i < leaf_refs.size();) {
        size_t j = i;
        while (j < leaf_refs.size() && leaf_refs[j].prim == leaf_refs[i].prim) ++j;
        const TriangleRecord& tri = triangles[leaf_refs[i].record];
        const Box tb = triangle_bounds(tri);
        if (j - i == 1) {
            // The whole triangle inside its leaf box and every ancestor's.
            ++st.unsplit_triangles;
            Box failed{};
            const bool ok =
                chain_holds(box_of, parent, leaf_refs[i].node, leaf_refs[i].slot, max_levels, [&](const Box& b) {
                    failed = b;
                    return contains(b, tb);
                });
            if (!ok)
                return fail_deep(id.contain, "triangle " + std::to_string(tri.prim) + " bounds " + box_text(tb) +
                                                 " are not inside the box " + box_text(failed) +
                                                 " of its leaf or of an ancestor");
        } else {
            // Every lattice point of a split triangle lies in the leaf box of some reference
            // and in every ancestor box of that leaf.
            ++st.split_triangles;
            for (size_t k = i; k < j; ++k)
                if (!overlaps(box_of(leaf_refs[k].node, leaf_refs[k].slot), tb))
                    return fail_deep(id.cover, "a reference of triangle " + std::to_string(tri.prim) +
                                                   " has a leaf box that misses the triangle");
            const float* v[3] = {tri.v0, tri.v1, tri.v2};
            constexpr int kSteps = 8;  // (kSteps+1)(kSteps+2)/2 = 45 lattice points, vertices included
            for (int a = 0; a <= kSteps; ++a) {
                for (int b = 0; a + b <= kSteps; ++b) {
                    const double wa = double(a) / kSteps, wb = double(b) / kSteps, wc = 1.0 - wa - wb;
                    double p[3];
                    for (int ax = 0; ax < 3; ++ax)
                        p[ax] = (a == kSteps) ? double(v[0][ax])
                                : (b == kSteps) ? double(v[1][ax])
                                : (a + b == 0) ? double(v[2][ax])
                                : wa * double(v[0][ax]) + wb * double(v[1][ax]) + wc * double(v[2][ax]);
                    bool covered = false;
                    for (size_t k = i; k < j && !covered; ++k)
                        covered = chain_holds(box_of, parent, leaf_refs[k].node, leaf_refs[k].slot, max_levels,
                                              [&](const Box& box) { return contains_point(box, p); });
                    ++st.samples;
                    if (!covered)
                        return fail_deep(id.cover, "a point of split triangle " + std::to_string(tri.prim) +
                                                       " is inside none of its " + std::to_string(j - i) +
                                                       " references' leaf-to-root box chains");
                }
            }
        }
        i = j;
    }
    return Result::success();
}

/// Child c's box of a binary node (the Aila-Laine layout of spec 3.6).
Box bvh2_box(const Bvh2Node& n, int c) {
    Box b;
    if (c == 0) b = {{n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z}};
    else b = {{n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z}};
    return b;
}

/// Parent links of a wide tree whose structure passed validation (D1); false on a child
/// out of order or range.
bool wide_parents(std::span<const CwbvhNode> nodes, std::vector<Parent>& parent, uint64_t& edges) {
    parent.assign(nodes.size(), Parent{});
    for (size_t i = 0; i < nodes.size(); ++i)
        for (int s = 0; s < kWidth; ++s) {
            if (!meta_is_internal(nodes[i].meta[s])) continue;
            const uint32_t c = internal_child_index(nodes[i], s);
            if (c <= i || c >= nodes.size()) return false;
            parent[c] = {uint32_t(i), uint8_t(s)};
            ++edges;
        }
    return true;
}

}  // namespace

Result deep_check_two_level(std::span<const TriangleRecord> triangles, const TwoLevelView& scene,
                            DeepCheckStats* stats) {
    DeepCheckStats local;
    DeepCheckStats& st = stats ? *stats : local;
    auto fail_d7 = [](const std::string& what) {
        return Result::fail(Status::kCorrupt, 0, "deep check D7: " + what);
    };
    // Mesh boxes contain their vertices (object space).
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
        const MeshRecord& mr = scene.meshes[m];
        const Box mb{{mr.lo[0], mr.lo[1], mr.lo[2]}, {mr.hi[0], mr.hi[1], mr.hi[2]}};
        if (uint64_t(mr.tri_first) + mr.tri_count > triangles.size())
            return fail_d7("mesh " + std::to_string(m) + ": TRIS range out of range");
        for (uint64_t t = mr.tri_first; t < uint64_t(mr.tri_first) + mr.tri_count; ++t)
            if (!contains(mb, triangle_bounds(triangles[t])))
                return fail_d7("mesh " + std::to_string(m) + ": box " + box_text(mb) + " does not contain TRIS record " +
                               std::to_string(t) + " " + box_text(triangle_bounds(triangles[t])));
    }
    // TLAS parent links (D1 on the top level).
    std::vector<Parent> parent;
    if (!wide_parents(scene.top_nodes, parent, st.internal_edges))
        return Result::fail(Status::kCorrupt, 0, "deep check D1: TLAS: a child is out of order or range");
    std::vector<uint8_t> seen(scene.instances.size(), 0);
    const auto box_of = [&](uint32_t node, int slot) { return decoded_box(scene.top_nodes[node], slot); };
    for (size_t i = 0; i < scene.top_nodes.size(); ++i) {
        const CwbvhNode& n = scene.top_nodes[i];
        for (int s = 0; s < kWidth; ++s) {
            const uint8_t meta = n.meta[s];
            if (meta_is_empty(meta) || meta_is_internal(meta)) continue;
            for (int k = 0; k < meta_leaf_count(meta); ++k) {
                const uint64_t j = uint64_t(n.tri_base) + uint64_t(meta_leaf_offset(meta)) + uint64_t(k);
                if (j >= scene.instances.size() || seen[j] != 0)
                    return fail_d7("TLAS node " + std::to_string(i) + " names instance " + std::to_string(j) +
                                   " out of range or twice");
                seen[j] = 1;
                const InstanceRecord& inst = scene.instances[j];
                if (inst.mesh >= scene.meshes.size())
                    return fail_d7("instance " + std::to_string(j) + ": mesh out of range");
                const MeshRecord& mr = scene.meshes[inst.mesh];
                // The world box holds the mesh box's image (recomputed with the rounding bound of 3.10).
                Box image;
                transform_box(inst.object_to_world, mr.lo, mr.hi, image.lo, image.hi);
                const Box world{{inst.world_lo[0], inst.world_lo[1], inst.world_lo[2]},
                                {inst.world_hi[0], inst.world_hi[1], inst.world_hi[2]}};
                if (!contains(world, image))
                    return fail_d7("instance " + std::to_string(j) + ": world box " + box_text(world) +
                                   " does not contain the transformed mesh box " + box_text(image));
                Box failed{};
                if (!chain_holds(box_of, parent, uint32_t(i), s, 64, [&](const Box& b) {
                        failed = b;
                        return contains(b, world);
                    }))
                    return fail_d7("instance " + std::to_string(j) + ": world box " + box_text(world) +
                                   " is not inside the TLAS box " + box_text(failed) + " of its leaf or of an ancestor");
                if (scene.bounds != nullptr) {
                    const Box bn{{scene.bounds->lo[0], scene.bounds->lo[1], scene.bounds->lo[2]},
                                 {scene.bounds->hi[0], scene.bounds->hi[1], scene.bounds->hi[2]}};
                    if (!contains(bn, world))
                        return fail_d7("instance " + std::to_string(j) + ": world box " + box_text(world) +
                                       " is not inside BNDS " + box_text(bn));
                }
                ++st.instances;
            }
        }
    }
    for (size_t j = 0; j < seen.size(); ++j)
        if (seen[j] == 0) return fail_d7("instance " + std::to_string(j) + " is in no TLAS leaf");
    return Result::success();
}

Result deep_check(std::span<const CwbvhNode> nodes, std::span<const TriangleRecord> triangles,
                  uint64_t stored_triangles, DeepCheckStats* stats) {
    DeepCheckStats local;
    DeepCheckStats& st = stats ? *stats : local;
    st = DeepCheckStats{};
    auto fail_deep = [](const char* id, const std::string& what) {
        return Result::fail(Status::kCorrupt, 0, std::string("deep check ") + id + ": " + what);
    };

    // Every stored triangle has a record (D4), so a larger count cannot be right; checked before
    // anything is sized by it (the count comes from the file: PMAP's total, up to 2^32).
    if (stored_triangles > triangles.size())
        return fail_deep("D4", std::to_string(stored_triangles) + " stored triangles but only " +
                                   std::to_string(triangles.size()) + " TRIS records");
    // Parent links, every record's leaf slot, and references per stored triangle.
    std::vector<Parent> parent(nodes.size());
    std::vector<uint32_t> refs(stored_triangles, 0);
    std::vector<LeafRef> leaf_refs;
    leaf_refs.reserve(triangles.size());
    for (size_t i = 0; i < nodes.size(); ++i) {
        const CwbvhNode& n = nodes[i];
        for (int s = 0; s < kWidth; ++s) {
            const uint8_t meta = n.meta[s];
            if (meta_is_empty(meta)) continue;
            if (meta_is_internal(meta)) {
                const uint32_t c = internal_child_index(n, s);
                if (c <= i || c >= nodes.size())
                    return fail_deep("D1", "node " + std::to_string(i) + " child out of order or range");
                parent[c] = {uint32_t(i), uint8_t(s)};
                ++st.internal_edges;
                continue;
            }
            const uint32_t first = n.tri_base + uint32_t(meta_leaf_offset(meta));
            for (int k = 0; k < meta_leaf_count(meta); ++k) {
                const uint32_t r = first + uint32_t(k);
                if (r >= triangles.size() || triangles[r].prim >= stored_triangles)
                    return fail_deep("D4", "node " + std::to_string(i) + " references a record out of range");
                ++refs[triangles[r].prim];
                leaf_refs.push_back({triangles[r].prim, r, uint32_t(i), uint8_t(s)});
            }
        }
    }
    for (uint64_t p = 0; p < stored_triangles; ++p)
        if (refs[p] == 0) return fail_deep("D4", "stored triangle " + std::to_string(p) + " is in no leaf");

    // D2: unsplit triangles lie inside their leaf box. D3 for the split ones.
    const auto box_of = [&](uint32_t node, int slot) { return decoded_box(nodes[node], slot); };
    return check_geometry(triangles, leaf_refs, parent, box_of, 64, CheckNames{"D2", "D3", ""}, st);
}

Result deep_check_bvh2(std::span<const Bvh2Node> nodes, bool leaf_ranges, std::span<const TriangleRecord> triangles,
                       uint64_t stored_triangles, DeepCheckStats* stats) {
    DeepCheckStats local;
    DeepCheckStats& st = stats ? *stats : local;
    st = DeepCheckStats{};
    const std::string section = leaf_ranges ? "BV2L" : "BVH2";
    auto fail_deep = [&](const char* id, const std::string& what) {
        return Result::fail(Status::kCorrupt, 0, std::string("deep check ") + id + ": " + section + ": " + what);
    };
    if (nodes.empty()) return fail_deep("D5", "no nodes");
    // Every stored triangle has a record (D4), so a larger count cannot be right; checked before
    // anything is sized by it.
    if (stored_triangles > triangles.size())
        return fail_deep("D5", std::to_string(stored_triangles) + " stored triangles but only " +
                                   std::to_string(triangles.size()) + " TRIS records");
    std::vector<Parent> parent(nodes.size());
    std::vector<uint8_t> leaves_of(triangles.size(), 0);  // leaves holding each record (saturates at 2)
    std::vector<LeafRef> leaf_refs;
    leaf_refs.reserve(triangles.size());
    for (size_t i = 0; i < nodes.size(); ++i) {
        const Bvh2Node& n = nodes[i];
        // A tree over a single record: one node whose two children are both that leaf (3.6).
        const bool twin = nodes.size() == 1 && n.child[0] < 0 && n.child[0] == n.child[1] &&
                          n.leaf_count[0] == n.leaf_count[1];
        for (int c = 0; c < 2; ++c) {
            const int32_t child = n.child[c];
            if (child >= 0) {
                if (uint64_t(child) <= i || uint64_t(child) >= nodes.size())
                    return fail_deep("D5", "node " + std::to_string(i) + " child out of order or range");
                parent[size_t(child)] = {uint32_t(i), uint8_t(c)};
                ++st.internal_edges;
                continue;
            }
            if (twin && c == 1) continue;
            const uint64_t first = uint32_t(~child);
            const uint64_t count = leaf_ranges ? n.leaf_count[c] : 1;
            if (first > triangles.size() || count > triangles.size() - first)
                return fail_deep("D5", "node " + std::to_string(i) + " leaf references records out of range");
            for (uint64_t r = first; r < first + count; ++r) {
                if (triangles[r].prim >= stored_triangles)
                    return fail_deep("D5", "record " + std::to_string(r) + " names a stored triangle out of range");
                if (leaves_of[r] != 0)
                    return fail_deep("D5", "record " + std::to_string(r) + " is in more than one leaf");
                leaves_of[r] = 1;
                leaf_refs.push_back({triangles[r].prim, uint32_t(r), uint32_t(i), uint8_t(c)});
            }
        }
    }
    std::vector<uint8_t> reached(stored_triangles, 0);
    for (const LeafRef& ref : leaf_refs) reached[ref.prim] = 1;
    for (uint64_t r = 0; r < triangles.size(); ++r)
        if (leaves_of[r] == 0) return fail_deep("D5", "record " + std::to_string(r) + " is in no leaf");
    for (uint64_t p = 0; p < stored_triangles; ++p)
        if (reached[p] == 0) return fail_deep("D5", "stored triangle " + std::to_string(p) + " is in no leaf");
    const auto box_of = [&](uint32_t node, int slot) { return bvh2_box(nodes[node], slot); };
    const std::string what = section + ": ";
    return check_geometry(triangles, leaf_refs, parent, box_of, 65, CheckNames{"D6", "D6", what.c_str()}, st);
}

}  // namespace cwbvh
