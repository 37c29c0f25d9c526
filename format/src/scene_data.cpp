#include "cwbvh/format/scene_data.h"

#include "cwbvh/format/sections.h"

namespace cwbvh {

void add_scene_sections(Writer& writer, const SceneSections& scene) {
    auto add = [&](uint32_t type, uint32_t element_size, uint64_t count, const void* data) {
        writer.add_section(type, default_section_flags(type), element_size, count,
                           std::span<const uint8_t>(static_cast<const uint8_t*>(data), element_size * count));
    };
    add(kSectionNodes, sizeof(CwbvhNode), scene.nodes.size(), scene.nodes.data());
    add(kSectionTriangles, sizeof(TriangleRecord), scene.triangles.size(), scene.triangles.data());
    add(kSectionSourceMap, sizeof(SourceRange), scene.source_ranges.size(), scene.source_ranges.data());
    add(kSectionBounds, sizeof(SceneBounds), 1, scene.bounds);
    if (scene.two_level()) {  // all three or none (rule 6001); an empty one fails validation (4011)
        add(kSectionMeshes, sizeof(MeshRecord), scene.meshes.size(), scene.meshes.data());
        add(kSectionInstances, sizeof(InstanceRecord), scene.instances.size(), scene.instances.data());
        add(kSectionTopNodes, sizeof(CwbvhNode), scene.top_nodes.size(), scene.top_nodes.data());
    }
    if (scene.build_info) add(kSectionBuildInfo, sizeof(BuildInfo), 1, scene.build_info);
    if (!scene.source_names.empty())
        add(kSectionSourceNames, 1, scene.source_names.size(), scene.source_names.data());
    if (!scene.bvh2.empty())
        add(scene.bvh2_leaf_ranges ? kSectionBvh2Leaves : kSectionBvh2, sizeof(Bvh2Node), scene.bvh2.size(),
            scene.bvh2.data());
    if (!scene.vertices.empty()) add(kSectionVertices, 12, scene.vertices.size() / 3, scene.vertices.data());
    if (!scene.indices.empty()) add(kSectionIndices, 12, scene.indices.size() / 3, scene.indices.data());
}

SceneSections SceneData::sections() const {
    SceneSections s;
    s.nodes = nodes;
    s.triangles = triangles;
    s.source_ranges = source_ranges;
    s.bounds = &bounds;
    s.build_info = build_info ? &*build_info : nullptr;
    s.source_names = {reinterpret_cast<const uint8_t*>(source_names.data()), source_names.size()};
    s.bvh2 = bvh2;
    s.bvh2_leaf_ranges = bvh2_leaf_ranges;
    s.vertices = vertices;
    s.indices = indices;
    s.meshes = meshes;
    s.instances = instances;
    s.top_nodes = top_nodes;
    return s;
}

SceneData SceneData::copy_of(const SceneSections& s) {
    SceneData d;
    d.nodes.assign(s.nodes.begin(), s.nodes.end());
    d.triangles.assign(s.triangles.begin(), s.triangles.end());
    d.source_ranges.assign(s.source_ranges.begin(), s.source_ranges.end());
    if (s.bounds) d.bounds = *s.bounds;
    if (s.build_info) d.build_info = *s.build_info;
    d.bvh2.assign(s.bvh2.begin(), s.bvh2.end());
    d.bvh2_leaf_ranges = s.bvh2_leaf_ranges;
    d.vertices.assign(s.vertices.begin(), s.vertices.end());
    d.indices.assign(s.indices.begin(), s.indices.end());
    d.source_names.assign(s.source_names.begin(), s.source_names.end());
    d.meshes.assign(s.meshes.begin(), s.meshes.end());
    d.instances.assign(s.instances.begin(), s.instances.end());
    d.top_nodes.assign(s.top_nodes.begin(), s.top_nodes.end());
    return d;
}

}  // namespace cwbvh
