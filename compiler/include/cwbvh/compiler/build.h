// Binary BVH builders of cwbvhc: Scene -> BinaryBvh (one triangle reference
// per leaf, nodes in canonical depth-first order, root = node 0).
//   build_sbvh   : own SBVH (Stich, Friedrich, Dietrich 2009), oneTBB-parallel,
//                  bit-identical output for any thread count.
//   build_embree : Embree 3 rtcBuildBVH (RTC_BUILD_QUALITY_HIGH, spatial splits
//                  through our triangle-clipping splitPrimitive callback), run
//                  single-threaded so that its output is deterministic too.
// Host-only.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/float_round.h"
#include "cwbvh/format/status.h"
#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

struct Progress;

/// Default of SbvhConfig::split_alpha (and of cwbvhc --split-alpha). Stich
/// et al. suggest 1e-5; 3e-5 skips the spatial-split search on nodes whose
/// best object split overlaps less, which cut the dragon's SBVH by ~12% (2
/// threads, 0.82 -> 0.72 s). Against 1e-5, on every shared scene: at most
/// +0.25% binary SAH and +0.31% wide SAH (fg_terrain_iceland), -0.05%
/// children per node (kicad_board), never more bytes per triangle; 5e-5:
/// +0.60% / +0.71%, 1e-4: +1.5% / +1.7% (issue 11 allows 1% against its
/// start). Tables: bench/results/quality/2026-11-25-split-alpha.
inline constexpr float kDefaultSplitAlpha = 3e-5f;

struct SbvhConfig {
    /// Stich et al. 2009, section 4.5: spatial splits are only tried at a node
    /// when the surface area of the overlap of the best object split's two
    /// children, divided by the root's surface area, exceeds alpha.
    /// 1 = never (plain SAH BVH), 0 = always try.
    float split_alpha = kDefaultSplitAlpha;
    /// Binary SAH constants (C_t, C_i). Because every leaf holds exactly one
    /// reference (the collapse needs it), a node is always split and the split
    /// choice minimises A_L*N_L + A_R*N_R whatever these are; they are passed to
    /// Embree (traversalCost/intersectionCost) and kept for documentation.
    float cost_traversal = 1.0f, cost_intersect = 1.0f;
    /// Spatial split bins per axis (Stich et al. 2009, section 4.3). Object
    /// splits do a full SAH sweep over centroid-sorted references for nodes of
    /// up to kSweepMaxRefs references and use kObjectBins centroid bins above.
    int bins = 32;
    /// Reference budget: references <= (1 + x) * triangles. The budget is
    /// handed down the tree deterministically (each child gets a share of the
    /// remaining duplicates proportional to its references' box areas); where
    /// a subtree's share is exhausted only object splits are made there.
    /// Default 0.15: every file of ../shared/scenes and assimp's Draco glTF
    /// then stays within 55 bytes per input triangle with a margin (the
    /// spec's size goal; 48.2-54.0 measured; with 1.0, sponza, torcs, fg_cg57
    /// and iceland reach 57-62, with 0.2 assimp's 2CylinderEngine 55.9) for a
    /// binary SAH 0-3.4 % above the unlimited build's.
    double max_reference_growth = 0.15;
    /// Nodes of fewer references never try a spatial split (2 = every node).
    /// Default 16: the compile's instructions -21% (callgrind, dragon_res2) for
    /// at most +0.23% binary SAH, +0.19% wide SAH and no more bytes per
    /// triangle on every shared scene (build_sbvh.cpp has the measurements).
    /// Scenes of large, crowded triangles (a random soup) then get their
    /// duplicates only where the budget allows them higher up.
    uint32_t min_spatial_refs = 16;
    /// 0 = TBB default; the output does NOT depend on it.
    int threads = 0;
};

/// `progress` (optional) gets the scene's triangle count spread over the
/// subtrees as they finish: it has advanced by exactly triangle_count() when
/// this returns true. It never influences the tree.
Result build_sbvh(const Scene& scene, const SbvhConfig& config, BinaryBvh& out, Progress* progress = nullptr);
Result build_embree(const Scene& scene, const SbvhConfig& config, BinaryBvh& out);
/// The SBVH builder's object-split SAH (binned for large nodes, full sweep for
/// small ones) over boxes instead of triangles, without spatial splits: the
/// top level of a two-level scene. Leaf i holds box index i (BinaryNode::prim).
/// Boxes must be finite and non-empty. Same canonical layout and determinism.
Result build_boxes(const std::vector<Aabb>& boxes, const SbvhConfig& config, BinaryBvh& out);

/// Spec formula: sum over internal nodes C_node*A(n)/A(root) + sum over leaves
/// C_prim*A(leaf)/A(root), A = surface area. Returns 0 for an empty tree.
double sah_cost_binary(const BinaryBvh& bvh, float c_node = 1.0f, float c_prim = 0.3f);

// ---------------------------------------------------------------------------
// Helpers shared by both builders and used by tests.
// ---------------------------------------------------------------------------

// next_float_up / next_float_down: cwbvh/format/float_round.h (included above).

/// Conservative float box of the part of triangle `tri` with
/// slab_lo <= x[axis] <= slab_hi (either bound may be +-inf), intersected with
/// `ref` (the reference's previous box). The exact (real-number) clipped
/// polygon lies inside the result: edge/plane intersections are computed in
/// double with an explicit error bound and rounded outward to float; the
/// axis coordinate is clamped to the slab planes exactly. Returns an empty box
/// (Aabb::empty()) when the triangle part inside the slab and `ref` is empty.
Aabb clip_triangle(const std::array<Vec3, 3>& tri, int axis, float slab_lo, float slab_hi,
                   const Aabb& ref);

/// clip_triangle for the consecutive slabs [planes[s], planes[s+1]],
/// s = 0..slabs-1 (planes non-decreasing), written to out[0..slabs). Bitwise
/// equal to calling clip_triangle per slab, but each plane's edge crossings
/// are computed once (used by the SBVH's spatial-split binning).
void chop_triangle(const std::array<Vec3, 3>& tri, int axis, const float* planes, int slabs,
                   const Aabb& ref, Aabb* out);

/// Like chop_triangle, in plain float arithmetic without outward rounding:
/// each box may be a few ulps too small or too large. For cost estimates only
/// (the SBVH's spatial-split binning); references' boxes always come from
/// clip_triangle.
void chop_triangle_estimate(const std::array<Vec3, 3>& tri, int axis, const float* planes, int slabs,
                            const Aabb& ref, Aabb* out);

/// Checks a BinaryBvh against its scene: canonical depth-first layout, root 0,
/// internal boxes contain their children's boxes, every leaf box meets its
/// triangle's box, every triangle has >= 1 leaf, `references` == leaves, and
/// `samples` random points (double) on triangles each lie in some reference
/// box of their triangle (tolerance 1e-12 relative to coordinate magnitude,
/// far below one float ulp). Returns false with a message on the first failure.
Result validate_binary_bvh(const Scene& scene, const BinaryBvh& bvh, int samples = 4000,
                                       uint64_t seed = 1);

}  // namespace cwbvh::compiler
