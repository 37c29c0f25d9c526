// (node, ray) pairs that exercise the fast node test on a scene's own nodes: each ray is
// aimed at a point of a random child box of a drawn node, from up to two grid extents
// away (a quarter of them from 100), some nearly axis-parallel, some with tmin > 0 or a
// finite tmax; only rays that take the fast test are kept. Deterministic in the seed.
// Used by the device self-check (fast_node_selfcheck.h) and by the node test's contract
// test on compiled trees (tests/traverse/node_intersect_test.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/ray.h"

namespace cwbvh {

struct FastNodePairs {
    NodeScale scale;                 ///< node_scale of the whole node array
    std::vector<CwbvhNode> nodes;    ///< pair i's node
    std::vector<Ray> rays;           ///< pair i's ray (tmin, tmax as drawn)
    std::vector<NodeRay> node_rays;  ///< its NodeRay with the fast test enabled
};

/// Up to `pairs` pairs from nodes[0, count) (fewer when the fast test refuses many rays;
/// none when it cannot take the scene).
FastNodePairs make_fast_node_pairs(const CwbvhNode* nodes, size_t count, uint64_t seed, size_t pairs);

}  // namespace cwbvh
