// `cwbvh validate --deep`: geometric checks of a compiled file that the
// structural validator does not make (they prove the tree is *right*, not just
// well-formed). Runs on a file that already passed validate(); O(nodes +
// references x depth). Checks (spec section "Deep checks"):
//   D1 structure: children after their parent and in range (parent links).
//   D2 containment: a triangle stored once (not split) lies, with its exact
//      float bounds, inside the decoded box of its leaf slot and of every
//      ancestor slot up to the root: every box a ray must enter to reach it.
//      (Decoded boxes need not nest: a child's box is rounded outward on its
//      own, finer grid and may poke out of its parent's decoded box; what
//      matters is that the geometry lies inside every box on its path.)
//   D3 coverage of split triangles: every reference's leaf box meets the
//      triangle's bounds, and each of 45 lattice points on the triangle
//      (vertices included, computed in double) lies inside the whole
//      leaf-to-root box chain of at least one reference (tolerance 2^-40 of
//      the coordinate magnitude, far below one float ulp).
//   D4 every stored triangle 0..count-1 is referenced by at least one record
//      (so the PMAP total is at most the TRIS count; checked before allocating).
//   In a two-level file (spec 3.9) NODE holds one tree per mesh: deep_check
//   walks each leaf up to its own tree's root (a node without parent), so D1-D4
//   run per mesh, in object space, with the same call.
// And over the top level of a two-level file, deep_check_two_level:
//   D7 every mesh box contains its TRIS vertices; every instance's world box
//      contains the image of its mesh box (transform_box, spec 3.10); the decoded
//      TLAS box of its leaf slot and of every ancestor slot contains the world
//      box; BNDS contains every world box. (Also D1 over TLAS.)
// And over a binary BVH section (BVH2 or BV2L), deep_check_bvh2:
//   D5 every TRIS record is in exactly one leaf (leaf ranges in range) and every
//      stored triangle is reached.
//   D6 D2 and D3 over the binary tree's child boxes: every box contains the
//      geometry of its subtree (inverted or shrunken boxes fail).
#pragma once

#include <cstdint>
#include <span>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"

namespace cwbvh {

struct DeepCheckStats {
    uint64_t internal_edges = 0;     ///< parent slot -> child node links (D1)
    uint64_t unsplit_triangles = 0;  ///< checked by D2
    uint64_t split_triangles = 0;    ///< checked by D3
    uint64_t samples = 0;            ///< D3 lattice points tested
    uint64_t instances = 0;          ///< checked by D7
};

/// The top level of a two-level file (spans into the file; bounds may be null).
struct TwoLevelView {
    std::span<const MeshRecord> meshes;
    std::span<const InstanceRecord> instances;
    std::span<const CwbvhNode> top_nodes;
    const SceneBounds* bounds = nullptr;
};

/// D7 (and D1 on TLAS) over a two-level file that passed validate(); `triangles` is
/// TRIS. Adds to `stats` (internal_edges, instances) without resetting it, so it can
/// follow deep_check() with the same stats.
[[nodiscard]] Result deep_check_two_level(std::span<const TriangleRecord> triangles, const TwoLevelView& scene,
                                          DeepCheckStats* stats = nullptr);

/// `stored_triangles`: the number of stored triangles (PMAP total); every
/// TRIS.prim must be below it (the structural validator guarantees this).
[[nodiscard]] Result deep_check(std::span<const CwbvhNode> nodes, std::span<const TriangleRecord> triangles,
                                uint64_t stored_triangles, DeepCheckStats* stats = nullptr);

/// D5 and D6 over a binary BVH section: `leaf_ranges` true for BV2L (a leaf holds
/// `leaf_count` records), false for BVH2 (one record per leaf). Runs on a file that passed
/// validate(); `stored_triangles` as for deep_check.
[[nodiscard]] Result deep_check_bvh2(std::span<const Bvh2Node> nodes, bool leaf_ranges,
                                     std::span<const TriangleRecord> triangles, uint64_t stored_triangles,
                                     DeepCheckStats* stats = nullptr);

}  // namespace cwbvh
