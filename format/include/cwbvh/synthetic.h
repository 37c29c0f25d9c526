// A small, deterministic, valid scene built without the compiler: triangles
// on a Morton-ordered grid, a hand-rolled 8-wide tree with mixed leaf and
// internal children and gaps between used slots, conservative quantization
// by decode-and-correct, and a binary BVH over the triangle records (BVH2, or
// BV2L with leaf ranges). For
// tests, fuzz seeds, test vectors and the load benchmark; not a BVH builder.
#pragma once

#include <cstdint>

#include "cwbvh/scene_data.h"

namespace cwbvh {

struct SyntheticOptions {
    uint32_t triangles = 40;       ///< 0 gives an empty scene (root with no children)
    uint64_t seed = 1;             ///< vertex jitter
    bool build_info = true;        ///< emit BILD
    bool bvh2 = true;              ///< emit a binary BVH (needs >= 1 triangle)
    bool bvh2_leaf_ranges = false; ///< as BV2L, leaves of up to 3 records (false: BVH2, one record per leaf)
    bool source_geometry = true;   ///< emit VERT, INDX and SRCN
};

SceneData make_synthetic_scene(const SyntheticOptions& options = {});

}  // namespace cwbvh
