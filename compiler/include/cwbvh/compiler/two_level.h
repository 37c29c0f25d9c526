// Two-level scenes (format 1.2, issue 19) in the compiler core: every
// distinct mesh through the same core as a single-level scene (SBVH, optimal
// collapse, auction slots, conservative quantization), the meshes in
// parallel; their NODE/TRIS concatenated with absolute indices; a top level
// (TLAS) built by the same core over the instances' world boxes (object
// splits only, leaves of <= 3 instances), with INST in its leaf order.
//
//   InstancedScene --compile_two_level--> TwoLevelResult --write_two_level--> file
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "cwbvh/compiler/core.h"
#include "cwbvh/compiler/model.h"
#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"

namespace cwbvh::compiler {

struct Progress;

/// Largest accepted condition number (infinity norm, in double) of an
/// instance transform's linear part (spec 3.10's bound, 2^20): a ray moved
/// into object space loses about log2(cond) of float's 24 bits.
inline constexpr double kMaxInstanceCondition = 0x1p20;

struct TwoLevelResult {
    std::vector<CwbvhNode> nodes;           ///< NODE: the bottom levels one after another (absolute indices)
    std::vector<TriangleRecord> triangles;  ///< TRIS: their records one after another (prim: global stored id)
    std::vector<SourceRange> source_ranges; ///< PMAP over all meshes' stored triangles
    std::vector<MeshRecord> meshes;         ///< MESH
    std::vector<InstanceRecord> instances;  ///< INST, in TLAS leaf order
    std::vector<CwbvhNode> tlas;            ///< TLAS: leaves index INST
    SceneBounds bounds{};                   ///< BNDS: union of the instance world boxes
    BuildInfo build_info{};                 ///< BILD: distinct triangles, summed over the meshes
    std::vector<uint8_t> source_names;      ///< SRCN

    uint64_t references = 0, binary_nodes = 0, spatial_splits = 0;
    uint32_t wide_depth = 0;   ///< deepest bottom level (root = 1)
    uint32_t tlas_depth = 0;   ///< levels of TLAS
    uint32_t max_leaf_triangles = 0;
    double avg_children = 0;   ///< over all bottom-level nodes
    double sah_binary = 0, sah_wide = 0;  ///< triangle-weighted means over the meshes
    /// Per core phase (sbvh, collapse, slots, encode), seconds summed over the
    /// meshes (they run in parallel: CPU time, not wall time).
    std::vector<std::pair<std::string, double>> mesh_phase_seconds;
};

/// The instance record of placement `p` of a mesh with object-space bounds
/// mesh.lo/hi: object_to_world = RN(p's double matrix), world_to_object = RN
/// of the double inverse of that float matrix, world box = the conservative
/// box of the mesh box's corners (rounded outward), widened by
/// cond * 2^-21 * (largest world coordinate + |translation|) for the float
/// world_to_object the traversal moves rays with (two_level.cpp).
/// Errors (kBadInput, message without file name): an entry beyond float range,
/// a singular transform, a condition number above kMaxInstanceCondition, a
/// world box beyond the importer's coordinate bound.
// TODO(lead): switch to format/'s host transform helpers (double inverse,
// condition number, conservative world box) once tl-fmt is merged; this is
// the only copy in the compiler.
Result make_instance_record(const Placement& p, const MeshRecord& mesh, InstanceRecord& out);

/// Compiles every mesh (in parallel, output independent of the thread count),
/// concatenates them, builds the instance records and the top level.
/// `file` names the input in error messages ("<file>: glTF node N: ...").
/// Each mesh must have >= 1 triangle and at least one placement must exist.
/// Phases (through `run`): meshes (counts the distinct triangles: `progress`,
/// optional, advances by a mesh's triangles when it is done), assemble,
/// instances, tlas.
Result compile_two_level(const InstancedScene& scene, const CoreOptions& options, const std::string& file,
                         TwoLevelResult& out, const PhaseRunner& run = {}, Progress* progress = nullptr);

/// Writes the file (sections of add_scene_sections, then MESH, INST, TLAS).
Result write_two_level(const TwoLevelResult& result, const std::string& path,
                       std::vector<std::pair<std::string, uint64_t>>& bytes, uint64_t& file_bytes);
/// The same file's bytes in memory.
Result two_level_bytes(const TwoLevelResult& result, std::vector<uint8_t>& out);

}  // namespace cwbvh::compiler
