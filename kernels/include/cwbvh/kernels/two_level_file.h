// An opened file's two-level scene (format 1.2: MESH, INST, TLAS) as the traversals take
// it: the one place that turns loader accessors into a TwoLevelScene (host only).
#pragma once

#include <cstdint>

#include "cwbvh/kernels/traverse_two_level.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh {

/// The sections a traversal opens: NODE, TRIS and the two-level sections (a two-level
/// file opened without them is refused by rule 4009), plus `extra`.
inline uint32_t trace_section_mask(uint32_t extra = 0) {
    return kMaskNodes | kMaskTriangles | kMaskTwoLevel | extra;
}

/// The file's two-level scene (reference node test: NodeScale{}); false for a
/// single-level file, which traverse_cwbvh / trace_cwbvh_cpu take as before.
inline bool two_level_scene(const File& f, TwoLevelScene& s) {
    if (!f.is_two_level() || f.top_nodes().empty()) return false;
    s = TwoLevelScene{f.top_nodes().data(), uint32_t(f.top_nodes().size()),
                      f.instances().data(), uint32_t(f.instances().size()),
                      f.meshes().data(),    uint32_t(f.meshes().size()),
                      f.nodes().data(),     uint32_t(f.nodes().size()),
                      f.triangles().data(), uint32_t(f.triangles().size())};
    return true;
}

}  // namespace cwbvh
