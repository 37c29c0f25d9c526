// Depth of the trees in NODE and BVH2 (root = depth 1). The traversal kernels
// keep one stack entry per level (two with triangle postponing), so the format
// bounds the depth (spec rules 5113 and 5606) and the compiler refuses to
// write deeper trees.
#pragma once

#include <cstdint>
#include <span>

#include "cwbvh/format/format.h"

namespace cwbvh {

/// Deepest NODE level accepted (the kernels' 64-entry stacks hold two entries per level).
inline constexpr uint32_t kMaxWideDepth = 32;
/// Deepest BVH2 level accepted (the baseline kernel's 64-entry stack holds one entry per level).
inline constexpr uint32_t kMaxBvh2Depth = 64;

/// Depth of a NODE array whose structure is already known to be valid
/// (children have larger indices than their parent and lie in range).
uint32_t wide_tree_depth(std::span<const CwbvhNode> nodes);

/// Depth of a BVH2 array whose structure is already known to be valid,
/// counting leaves as a level (a root with two leaves has depth 2).
uint32_t bvh2_tree_depth(std::span<const Bvh2Node> nodes);

}  // namespace cwbvh
