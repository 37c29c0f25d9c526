// An opened file's scene as the traversals take it: the one place that turns loader
// accessors into a TwoLevelScene (format 1.2: MESH, INST, TLAS) or a SceneView (the
// inline queries of query.h) on the host.
#pragma once

#include <cstdint>

#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/query.h"
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

/// The file's scene for inline queries on the host (query.h: intersect, occluded):
/// pointers into the mapped file, valid while it is open; two-level for a two-level
/// file. fast_node_test: with the fast node test's constants, as DeviceScene::view()
/// has them (node_scale over NODE, merged with TLAS for a two-level file), so that the
/// host runs what a kernel runs; the host emulates the device's half-precision
/// arithmetic bit for bit, which is slower than the reference test: for checking.
/// Without: the reference node test (the CPU reference's).
inline SceneView host_view(const File& f, bool fast_node_test = false) {
    SceneView v = single_level_view(f.nodes().data(), uint32_t(f.nodes().size()), f.triangles().data(),
                                    uint32_t(f.triangles().size()));
    two_level_scene(f, v.sections);
    if (fast_node_test && !f.nodes().empty()) {
        v.sections.node_scale = node_scale(f.nodes().data(), f.nodes().size());
        if (v.two_level())
            v.sections.node_scale =
                merge_node_scale(v.sections.node_scale, node_scale(f.top_nodes().data(), f.top_nodes().size()));
    }
    return v;
}

}  // namespace cwbvh
