// The two-level view of an open File (format 1.2: MESH, INST, TLAS) for the Python traces.
// The same few lines as tools/cwbvh/two_level.h; they belong in one home next to the loader
// (reported to the lead) and this file goes once that exists.
#pragma once

#include <cstdint>

#include "cwbvh/kernels/traverse_two_level.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh::python {

/// The file's two-level scene; false for a single-level file.
inline bool two_level_scene(const File& f, TwoLevelScene& s) {
    if (!f.is_two_level() || f.top_nodes().empty()) return false;
    s = TwoLevelScene{f.top_nodes().data(), uint32_t(f.top_nodes().size()),
                      f.instances().data(), uint32_t(f.instances().size()),
                      f.meshes().data(),    uint32_t(f.meshes().size()),
                      f.nodes().data(),     uint32_t(f.nodes().size()),
                      f.triangles().data(), uint32_t(f.triangles().size())};
    return true;
}

}  // namespace cwbvh::python
