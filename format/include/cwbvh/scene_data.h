// All sections of a scene in memory, and the one function that hands them to
// a Writer in spec order with the right flags. Used by the synthetic scene
// generator, the tests and (optionally) the compiler's emit stage.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "cwbvh/format.h"
#include "cwbvh/writer.h"

namespace cwbvh {

struct SceneData {
    std::vector<CwbvhNode> nodes;            ///< NODE
    std::vector<TriangleRecord> triangles;   ///< TRIS
    std::vector<SourceRange> source_ranges;  ///< PMAP (make_source_ranges builds it)
    SceneBounds bounds{};                    ///< BNDS
    std::optional<BuildInfo> build_info;     ///< BILD (absent if nullopt)
    std::vector<Bvh2Node> bvh2;              ///< BVH2 or BV2L (absent if empty)
    bool bvh2_leaf_ranges = false;           ///< write `bvh2` as BV2L (leaf ranges) instead of BVH2
    std::vector<float> vertices;             ///< VERT, 3 floats per vertex (absent if empty)
    std::vector<uint32_t> indices;           ///< INDX, 3 per stored triangle (absent if empty)
    std::string source_names;                ///< SRCN, names each followed by '\0' (absent if empty)
};

/// Adds the present sections of `scene` to `writer` (which keeps pointers
/// into `scene`: keep it alive until the writer has written).
void add_scene_sections(Writer& writer, const SceneData& scene);

}  // namespace cwbvh
