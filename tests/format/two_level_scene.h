// Small two-level scenes (format 1.2, spec 3.9-3.11) built in the tests: bottom
// levels compiled by the compiler core (make_synthetic_scene), instances made
// with make_instance (transform_host.h), and a TLAS quantized by the core's
// quantize_node. The layout is the one the spec's design note draws.
#pragma once

#include <cstdint>
#include <vector>

#include "cwbvh/format/scene_data.h"

namespace cwbvh::test {

/// One placement: a mesh index and a 3x4 object-to-world transform.
struct Placement {
    uint32_t mesh;
    float object_to_world[3][4];
    uint32_t source_node = kInvalidIndex;
};

/// Concatenates `meshes` (single-level scenes) into NODE/TRIS/PMAP + MESH with
/// absolute indices, places them, and builds a two-level TLAS over the placements:
/// the root's slot 0 is a leaf of the first min(2, n) instances, and up to 3 more
/// internal children hold up to 8 single-instance leaf slots each (so the TLAS has
/// two levels as soon as there are 3 instances). BNDS = union of the world boxes.
/// Throws std::runtime_error on a bad placement.
SceneData make_two_level(const std::vector<SceneData>& meshes, const std::vector<Placement>& placements);

/// The standard test scene: mesh 0 = 30 synthetic triangles (3 nodes), mesh 1 = 10
/// (1 node); 5 placements: identity, translated, rotated + scaled, mirrored
/// (negative determinant), and far translated.
SceneData standard_two_level();

/// The identity, a translation, a rotation about z by `degrees` with uniform scale.
Placement place(uint32_t mesh, float tx = 0, float ty = 0, float tz = 0, float degrees = 0, float scale = 1,
                bool mirror_x = false);

}  // namespace cwbvh::test
