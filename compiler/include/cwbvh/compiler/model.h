// The compiler's internal data model: what each stage hands to the next.
//   import_*  -> Scene (cleaned triangle soup + source map)
//   build_*   -> BinaryBvh (one triangle reference per leaf)
//   collapse  -> WideBvh  (8-wide, <=3 triangles per leaf, slots assigned)
//   encode    -> CwbvhNode[] + TriangleRecord[] (format/)
// Host-only (STL allowed).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"

namespace cwbvh::compiler {

using Vec3 = std::array<float, 3>;

/// Axis-aligned box in float. Empty: lo = +inf, hi = -inf.
struct Aabb {
    Vec3 lo{kInf, kInf, kInf};
    Vec3 hi{-kInf, -kInf, -kInf};
    static constexpr float kInf = __builtin_huge_valf();

    void grow(const Vec3& p) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = lo[a] < p[a] ? lo[a] : p[a];
            hi[a] = hi[a] > p[a] ? hi[a] : p[a];
        }
    }
    void grow(const Aabb& b) { grow(b.lo); grow(b.hi); }
    bool empty() const { return !(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2]); }
    /// Half surface area in double (the SAH only needs ratios).
    double half_area() const {
        if (empty()) return 0.0;
        const double dx = double(hi[0]) - lo[0], dy = double(hi[1]) - lo[1], dz = double(hi[2]) - lo[2];
        return dx * dy + dy * dz + dz * dx;
    }
};

/// Cleaned, merged input. Triangle i ("stored triangle id") has vertices
/// vertices[indices[i][k]] and comes from sources[i].
struct Scene {
    std::vector<Vec3> vertices;
    std::vector<std::array<uint32_t, 3>> indices;
    std::vector<SourceRef> sources;        ///< one per triangle (empty once turned into source_ranges)
    /// The PMAP runs of `sources` (make_source_ranges). cwbvhc makes them
    /// right after the import and frees `sources` (16 bytes per triangle,
    /// alive through every later peak); empty: the core makes them from
    /// `sources` when it writes the file.
    std::vector<SourceRange> source_ranges;
    std::vector<std::string> input_names;  ///< SourceRef::input indexes this

    uint64_t input_triangles = 0;          ///< before cleaning
    /// Dropped triangles by reason ("nonfinite", "degenerate", ...).
    std::map<std::string, uint64_t> dropped;
    /// Skipped non-triangle primitives by kind ("points", "lines", ...).
    std::map<std::string, uint64_t> skipped_primitives;

    size_t triangle_count() const { return indices.size(); }
    std::array<Vec3, 3> triangle(size_t i) const {
        return {vertices[indices[i][0]], vertices[indices[i][1]], vertices[indices[i][2]]};
    }
};

/// One placement of a bottom level of a two-level scene (design: issue 19).
struct Placement {
    uint32_t mesh = 0;                       ///< index into InstancedScene::meshes
    uint32_t source_node = kInvalidIndex;    ///< glTF node (kInvalidIndex: the merged identity instance)
    /// Affine 3x4, row-major, in double (the glTF node's world matrix):
    /// x_world[r] = m[4r]*x + m[4r+1]*y + m[4r+2]*z + m[4r+3].
    std::array<double, 12> object_to_world{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
};

/// A two-level scene: distinct meshes (bottom levels) and their placements.
/// A glTF mesh placed >= 2 times is one bottom level in object space; all
/// geometry placed once is merged, in world space, into one extra bottom level
/// (the last one) with one identity placement.
struct InstancedScene {
    std::vector<Scene> meshes;             ///< bottom levels, each cleaned on its own (stored ids local)
    std::vector<uint32_t> source_mesh;     ///< glTF mesh per bottom level (kInvalidIndex: merged)
    std::vector<Placement> placements;
    std::vector<std::string> input_names;  ///< SRCN
    uint64_t input_triangles = 0;          ///< distinct triangles before cleaning (all bottom levels)
    std::map<std::string, uint64_t> dropped;
    std::map<std::string, uint64_t> skipped_primitives;

    uint64_t distinct_triangles() const {
        uint64_t n = 0;
        for (const Scene& m : meshes) n += m.triangle_count();
        return n;
    }
    /// Triangles once every placement is expanded.
    uint64_t instanced_triangles() const {
        uint64_t n = 0;
        for (const Placement& p : placements) n += meshes[p.mesh].triangle_count();
        return n;
    }
};

/// Binary BVH with exactly one triangle reference per leaf. Node 0 is the
/// root. Nodes are in depth-first order (left subtree first) so that the
/// layout is canonical whatever the thread count.
/// 32 bytes: a leaf keeps its stored triangle id in child[0] and marks
/// child[1] invalid (an internal node has two valid children).
struct BinaryNode {
    Aabb box;                  ///< conservative bounds of the subtree (clipped for split references)
    uint32_t child[2] = {kInvalidIndex, kInvalidIndex};  ///< internal: children; leaf: {prim, kInvalidIndex}
    bool is_leaf() const { return child[1] == kInvalidIndex; }
    /// Leaf: the stored triangle id (kInvalidIndex for a node never made a leaf or internal).
    uint32_t prim() const { return child[0]; }
    /// Makes this node a leaf holding stored triangle `p`.
    void set_prim(uint32_t p) {
        child[0] = p;
        child[1] = kInvalidIndex;
    }
};
static_assert(sizeof(BinaryNode) == 32, "BinaryNode: 32 bytes");

struct BinaryBvh {
    std::vector<BinaryNode> nodes;
    uint64_t references = 0;   ///< number of leaves (>= triangle count with spatial splits)
    uint64_t spatial_splits = 0;
    uint64_t object_splits = 0;
};

/// Collapse cost model (Ylitie et al. 2017, section 3; constants in the spec).
struct CollapseConfig {
    float cost_node = 1.0f;   ///< C_node: cost of traversing one wide node
    float cost_prim = 0.3f;   ///< C_prim: cost of intersecting one triangle
    int max_leaf = kMaxLeafTriangles;
    CollapseKind kind = kCollapseOptimal;
    /// Fill WideBvh::binary_leaf_ref (4 bytes per binary node), which only the
    /// BVH2/BV2L encoder reads; the core turns it off when no such section is written.
    bool binary_leaf_refs = true;
};

/// 8-wide tree before quantization (Ylitie et al. 2017, section 3.1).
/// Produced by collapse_wide(), slots permuted by assign_slots(); the final
/// NODE/TRIS order is chosen by encode_cwbvh(), so the order of
/// WideBvh::nodes and WideBvh::leaf_refs is only required to be deterministic.
/// Exact boxes are not copied: every node and child names the binary node it
/// was collapsed from, whose box is its exact bounds (WideBvh::box), so the
/// binary tree must outlive every use of the boxes (the collapse, the slots,
/// the quantization, sah_cost_wide and the box part of verify_encoded).
struct WideChild {
    enum Kind : uint8_t { kEmpty, kInternal, kLeaf } kind = kEmpty;
    uint8_t ref_count = 0;           ///< kLeaf: 1..3 (after de-duplication)
    union {                          // one index per kind (GCC/Clang: either name reads the same bits)
        uint32_t node = kInvalidIndex;  ///< kInternal: index into WideBvh::nodes
        uint32_t first_ref;             ///< kLeaf: first index into WideBvh::leaf_refs
    };
    uint32_t bnode = kInvalidIndex;  ///< the collapsed binary node (its box: the exact, unquantized bounds)
};
static_assert(sizeof(WideChild) == 12, "WideChild: 12 bytes (eight per WideNode)");
struct WideNode {
    uint32_t bnode = kInvalidIndex;  ///< the binary node this wide node came from (its box: the exact bounds)
    std::array<WideChild, 8> slots;
    int child_count() const {
        int c = 0;
        for (const WideChild& ch : slots) c += ch.kind != WideChild::kEmpty;
        return c;
    }
};
struct WideBvh {
    std::vector<WideNode> nodes;        ///< node 0 = root (always internal)
    /// Stored triangle ids in leaf order (one per reference, duplicates of one
    /// triangle inside the same wide leaf removed); the TRIS section is this
    /// list, re-ordered by the encoder, with vertices attached.
    std::vector<uint32_t> leaf_refs;
    /// Per binary node: index into leaf_refs of that binary leaf's reference
    /// (kInvalidIndex for internal binary nodes). Two binary leaves with the
    /// same triangle in the same wide leaf share one entry. Used for BVH2; empty
    /// when CollapseConfig::binary_leaf_refs is false.
    std::vector<uint32_t> binary_leaf_ref;
    /// The tree the bnode indices name (set by collapse_wide; not owned).
    const BinaryBvh* binary = nullptr;

    /// Exact bounds of a child / a node (the binary tree must still be alive).
    const Aabb& box(const WideChild& c) const { return binary->nodes[c.bnode].box; }
    const Aabb& box(const WideNode& n) const { return binary->nodes[n.bnode].box; }
};

}  // namespace cwbvh::compiler
