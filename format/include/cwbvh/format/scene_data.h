// The sections of a scene, and the one function that hands them to a Writer:
// which optional sections are present is the caller's choice (absent = empty),
// their order and flags are decided here and only here. cwbvhc's emit stage
// (compiler/src/emit.cpp) writes every file through it; tests that craft a file
// by hand fill a SceneData.
#pragma once

#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/format/writer.h"

namespace cwbvh {

/// The sections of one file, not owned (spans into the producer's arrays).
struct SceneSections {
    std::span<const CwbvhNode> nodes;            ///< NODE
    std::span<const TriangleRecord> triangles;   ///< TRIS
    std::span<const SourceRange> source_ranges;  ///< PMAP
    const SceneBounds* bounds = nullptr;         ///< BNDS (required: must be set)
    const BuildInfo* build_info = nullptr;       ///< BILD (absent if null)
    std::span<const uint8_t> source_names;       ///< SRCN, names each followed by '\0' (absent if empty)
    std::span<const Bvh2Node> bvh2;              ///< BVH2 or BV2L (absent if empty)
    bool bvh2_leaf_ranges = false;               ///< write `bvh2` as BV2L (leaf ranges) instead of BVH2
    std::span<const float> vertices;             ///< VERT, 3 floats per vertex (absent if empty)
    std::span<const uint32_t> indices;           ///< INDX, 3 per stored triangle (absent if empty)
    // Two-level scenes (format 1.2, spec 3.9-3.11): all three written when any is non-empty.
    std::span<const MeshRecord> meshes;          ///< MESH: bottom levels, tiling NODE/TRIS/stored ids in order
    std::span<const InstanceRecord> instances;   ///< INST, in TLAS leaf order
    std::span<const CwbvhNode> top_nodes;        ///< TLAS: the top level (root 0); leaves index INST

    bool two_level() const { return !meshes.empty() || !instances.empty() || !top_nodes.empty(); }
};

/// All sections of a scene in memory (owned).
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
    std::vector<MeshRecord> meshes;          ///< MESH (two-level: all three non-empty; else all empty)
    std::vector<InstanceRecord> instances;   ///< INST
    std::vector<CwbvhNode> top_nodes;        ///< TLAS

    /// A view of this scene's sections (valid while the scene is alive and unchanged).
    SceneSections sections() const;
    /// An owned copy of `s`.
    static SceneData copy_of(const SceneSections& s);
};

/// Adds the present sections to `writer` (which keeps pointers into them: keep
/// them alive until the writer has written), in the order NODE, TRIS, PMAP, BNDS,
/// MESH, INST, TLAS, BILD, SRCN, BVH2/BV2L, VERT, INDX, with default_section_flags()
/// (MESH, INST, TLAS: all three when scene.two_level(), flagged required; the writer
/// then stamps minor 2). A scene without them gives the bytes a 1.1 writer gave.
void add_scene_sections(Writer& writer, const SceneSections& scene);
inline void add_scene_sections(Writer& writer, const SceneData& scene) { add_scene_sections(writer, scene.sections()); }

}  // namespace cwbvh
