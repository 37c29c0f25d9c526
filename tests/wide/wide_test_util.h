// Test-only helpers for the wide-BVH tests: random scenes, a simple
// top-down binary BVH builder (one reference per leaf, depth-first order),
// an OBJ reader (v/f lines) and a brute-force optimal collapse cost.
#pragma once

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "cwbvh/compiler/model.h"

namespace cwbvh::wide_test {

using compiler::Aabb;
using compiler::BinaryBvh;
using compiler::Scene;

/// n random small triangles in [0, extent]^3.
Scene random_scene(size_t n, uint32_t seed, float extent = 100.0f, float size = 2.0f);

enum class SplitMode { kMedian, kRandom, kChain };

/// Top-down builder over `refs` (stored triangle ids, may repeat to mimic
/// spatial-split duplicates): median split on the largest centroid axis,
/// uniformly random split position, or a chain (one leaf split off per
/// level: depth = refs.size()). Iterative; boxes = triangle boxes.
BinaryBvh build_binary(const Scene& scene, std::vector<uint32_t> refs, SplitMode mode, uint32_t seed = 1);
BinaryBvh build_binary(const Scene& scene, SplitMode mode = SplitMode::kMedian, uint32_t seed = 1);

/// Minimal OBJ reader: `v x y z` and `f i j k ...` (fan-triangulated, v/vt/vn
/// and negative indices accepted). Returns false if the file cannot be read.
bool read_obj(const std::string& path, Scene& scene);

/// Box store for hand-built wide trees (WideBvh::binary = &boxes): appends a
/// binary node holding `box` and returns its index (a bnode).
uint32_t add_box(BinaryBvh& boxes, const Aabb& box);

/// A wide leaf over leaf_refs[first, first + count) whose stored triangle ids
/// are first.. (the tests' leaf_refs are the identity), box = their union
/// (appended to `boxes`).
compiler::WideChild leaf_of(const Scene& scene, BinaryBvh& boxes, uint32_t first, uint32_t count);

/// Brute force: enumerates every valid collapse of a (tiny) binary tree —
/// every labelling of binary nodes as wide internal node / wide leaf /
/// eliminated — and returns the smallest unnormalised SAH cost
/// (C_node * A per internal, C_prim * distinct triangles * A per leaf).
double brute_force_min_cost(const BinaryBvh& bvh, double c_node, double c_prim, int max_leaf,
                            uint64_t* configurations = nullptr);

}  // namespace cwbvh::wide_test
