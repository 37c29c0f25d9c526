// A small, deterministic, valid scene for tests, fuzz seeds, test vectors, the
// load benchmark and the GPU check: triangles on a Morton-ordered grid (grouped
// into source primitives of 8, so PMAP has several runs), compiled by the
// compiler core (core.h: SBVH, collapse, slots, quantization, encoding,
// sections) exactly as cwbvhc compiles a mesh. Library cwbvh_synthetic.
#pragma once

#include <cstdint>

#include "cwbvh/format/scene_data.h"

namespace cwbvh {

struct SyntheticOptions {
    uint32_t triangles = 40;       ///< 0 gives an empty scene (root with no children)
    uint64_t seed = 1;             ///< vertex jitter
    bool build_info = true;        ///< emit BILD
    bool bvh2 = true;              ///< emit a binary BVH (needs >= 1 triangle)
    bool bvh2_leaf_ranges = false; ///< as BV2L, cut at the wide leaves (false: BVH2, one record per leaf)
    bool source_geometry = true;   ///< emit VERT, INDX and SRCN
    /// Moves the last triangle far from the grid, so that the root holds it as
    /// a leaf child next to internal children (the grid alone gives a root of
    /// internal children once there are more than ~60 triangles).
    bool outlier = false;
};

/// Throws std::logic_error if the core rejects the scene (a bug: it never should).
SceneData make_synthetic_scene(const SyntheticOptions& options = {});

}  // namespace cwbvh
