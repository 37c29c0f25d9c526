// The SAH figures cwbvhc reports (stats JSON, summary, BILD), by one formula
// for every tree so that builders and collapses compare directly (spec 3.5):
//   SAH = sum over internal nodes A(n)/A(root) + sum over leaves A(l)/A(root) * triangles(l)
// i.e. one unit per node visited and one per triangle tested, root included.
// The wide tree is measured on the *decoded* quantized boxes it will really be
// traversed with. (The collapse DP optimises its own cost model, C_node = 1,
// C_prim = 0.3, on exact boxes; that is a construction detail, not a report.)
#pragma once

#include <span>

#include "cwbvh/compiler/model.h"
#include "cwbvh/format/format.h"

namespace cwbvh::compiler {

/// Binary tree: every leaf holds one reference.
double report_sah_binary(const BinaryBvh& bvh);

/// Wide tree from the encoded nodes: an internal node's area is its decoded
/// slot box in its parent (the root's is `root`, the scene bounds), each leaf
/// slot counts its decoded box times its triangle count.
double report_sah_wide(std::span<const CwbvhNode> nodes, const Aabb& root);

/// report_sah_wide split into its two sums (normalised the same way):
/// `internal` = the node term (root included), `leaf` = the triangle term.
/// The same split on the exact boxes is sah_cost_wide(wide, 1, 0) and
/// sah_cost_wide(wide, 0, 1); decoded minus exact is the quantization loss.
struct WideSahParts {
    double internal = 0;
    double leaf = 0;
    double total = 0;  ///< report_sah_wide (one running sum in node order: == internal + leaf up to rounding)
};
WideSahParts report_sah_wide_parts(std::span<const CwbvhNode> nodes, const Aabb& root);

}  // namespace cwbvh::compiler
