// The section types this reader knows: names, element sizes, which ones a
// valid file must contain, and a bit per type for "validate/map only these".
#pragma once

#include <cstdint>
#include <string>

#include "cwbvh/format/format.h"

namespace cwbvh {

/// One bit per known section type; used by ValidateOptions/OpenOptions to
/// select the sections whose content is checked and handed out.
enum SectionMask : uint32_t {
    kMaskNodes = 1u << 0,
    kMaskTriangles = 1u << 1,
    kMaskSourceMap = 1u << 2,
    kMaskBounds = 1u << 3,
    kMaskBuildInfo = 1u << 4,
    kMaskBvh2 = 1u << 5,  ///< both binary BVH sections, BVH2 and BV2L (File::bvh2() gives the one present)
    kMaskVertices = 1u << 6,
    kMaskIndices = 1u << 7,
    kMaskSourceNames = 1u << 8,
    /// The three sections of a two-level file (format 1.2), MESH, INST and TLAS: all
    /// three or none (rule 6001). A two-level file opened with NODE selected must
    /// select them too (File::open refuses it otherwise, rule 4009).
    kMaskTwoLevel = 1u << 9,
    kMaskAll = (1u << 10) - 1,
};

struct SectionInfo {
    uint32_t type;          ///< FourCC
    uint32_t mask;          ///< SectionMask bit
    uint32_t element_size;  ///< the only element size a version-1 reader accepts
    bool mandatory;         ///< every valid file contains it
    const char* description;
    uint16_t since_minor;   ///< format 1.x that added the type; a writer stamps the largest among its sections
    bool required;          ///< writers set kSectionRequired (a reader that does not know the type must reject)
};

/// Known section types in spec order.
inline constexpr SectionInfo kKnownSections[] = {
    {kSectionNodes, kMaskNodes, sizeof(CwbvhNode), true, "compressed wide BVH nodes", 0, true},
    {kSectionTriangles, kMaskTriangles, sizeof(TriangleRecord), true, "triangle records in leaf order", 0, true},
    {kSectionSourceMap, kMaskSourceMap, sizeof(SourceRange), true, "stored triangle runs -> source primitive", 0,
     true},
    {kSectionBounds, kMaskBounds, sizeof(SceneBounds), true, "scene bounds", 0, true},
    // Two-level scenes (format 1.2, spec 3.9-3.11): optional as a group, required when present.
    {kSectionMeshes, kMaskTwoLevel, sizeof(MeshRecord), false, "bottom levels (meshes)", 2, true},
    {kSectionInstances, kMaskTwoLevel, sizeof(InstanceRecord), false, "instances in top-level leaf order", 2, true},
    {kSectionTopNodes, kMaskTwoLevel, sizeof(CwbvhNode), false, "top-level compressed wide BVH nodes", 2, true},
    {kSectionBuildInfo, kMaskBuildInfo, sizeof(BuildInfo), false, "build parameters and statistics", 0, false},
    {kSectionBvh2, kMaskBvh2, sizeof(Bvh2Node), false, "binary BVH, one triangle per leaf (Aila-Laine layout)", 0,
     false},
    {kSectionBvh2Leaves, kMaskBvh2, sizeof(Bvh2Node), false, "binary BVH with leaf ranges (Aila-Laine layout)", 1,
     false},
    {kSectionVertices, kMaskVertices, 12, false, "source vertices (float[3])", 0, false},
    {kSectionIndices, kMaskIndices, 12, false, "source vertex indices (uint32[3]) per stored triangle", 0, false},
    {kSectionSourceNames, kMaskSourceNames, 1, false, "NUL-terminated input file names", 0, false},
};

/// The entry of kKnownSections for `type`, or nullptr for an unknown type.
const SectionInfo* find_section_info(uint32_t type);

/// The FourCC as text ("NODE"); non-printable bytes as \xNN.
std::string section_name(uint32_t type);

/// The flags a writer should use for a known type (kSectionRequired for the
/// mandatory ones and the two-level ones, 0 otherwise).
uint32_t default_section_flags(uint32_t type);

}  // namespace cwbvh
