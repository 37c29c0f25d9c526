#include "cwbvh/scene_data.h"

#include "cwbvh/sections.h"

namespace cwbvh {

void add_scene_sections(Writer& writer, const SceneData& scene) {
    auto bytes = [](const void* p, size_t n) { return std::span<const uint8_t>(static_cast<const uint8_t*>(p), n); };
    auto add = [&](uint32_t type, uint32_t element_size, uint64_t count, const void* data) {
        writer.add_section(type, default_section_flags(type), element_size, count, bytes(data, element_size * count));
    };
    add(kSectionNodes, sizeof(CwbvhNode), scene.nodes.size(), scene.nodes.data());
    add(kSectionTriangles, sizeof(TriangleRecord), scene.triangles.size(), scene.triangles.data());
    add(kSectionSourceMap, sizeof(SourceRange), scene.source_ranges.size(), scene.source_ranges.data());
    add(kSectionBounds, sizeof(SceneBounds), 1, &scene.bounds);
    if (scene.build_info) add(kSectionBuildInfo, sizeof(BuildInfo), 1, &*scene.build_info);
    if (!scene.bvh2.empty())
        add(scene.bvh2_leaf_ranges ? kSectionBvh2Leaves : kSectionBvh2, sizeof(Bvh2Node), scene.bvh2.size(),
            scene.bvh2.data());
    if (!scene.vertices.empty()) add(kSectionVertices, 12, scene.vertices.size() / 3, scene.vertices.data());
    if (!scene.indices.empty()) add(kSectionIndices, 12, scene.indices.size() / 3, scene.indices.data());
    if (!scene.source_names.empty())
        add(kSectionSourceNames, 1, scene.source_names.size(), scene.source_names.data());
}

}  // namespace cwbvh
