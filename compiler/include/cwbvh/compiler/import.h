// Import stage of cwbvhc: mesh files -> cleaned, merged Scene (model.h).
//
//   import_scene(paths)            dispatch each file by magic/extension (import.cpp)
//     glTF 2.0 .gltf/.glb          tinygltf adapter           (import_gltf.cpp)
//     .obj .ply .off .stl          OpenMesh adapter           (import_openmesh.cpp)
//     .drc (and glTF Draco data)   Draco adapter              (import_draco.cpp)
//   -> RawInput per file -> clean_and_merge (clean.cpp) -> Scene
//
// No third-party type appears here. Nothing throws out of these functions.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

struct ImportOptions {
    /// glTF: tolerate recoverable spec violations (a node with several
    /// parents, an unknown entry in extensionsRequired) with a warning
    /// instead of an error. Never relaxes bounds checks.
    bool permissive = false;
    /// glTF: let an external buffer URI contain a ".." component (it can then
    /// name any file). Off by default: a buffer must lie in or below the folder
    /// of the file that names it. Absolute URIs are refused either way.
    bool allow_parent_uris = false;
};

/// Loads all inputs in order (SourceRef::input = position in `paths`), merges
/// and cleans them into `out` (replaced). Returns false with `error` set to one
/// line "<file>: <what is wrong>" on bad input; `warnings` gets one line per
/// warning ("<file>: ..."). Deterministic: same inputs, same Scene.
Result import_scene(const std::vector<std::string>& paths, const ImportOptions& options,
                                Scene& out, std::vector<std::string>& warnings);

/// Two-level import (issue 19's policy): one glTF input in which some mesh is
/// placed by more than one node gives `instanced` (is_instanced true); any
/// other input list gives `flat` exactly as import_scene does.
Result import_scene_instanced(const std::vector<std::string>& paths, const ImportOptions& options, Scene& flat,
                              InstancedScene& instanced, bool& is_instanced, std::vector<std::string>& warnings);

// ---------------------------------------------------------------------------
// Stage internals (used by import_scene and by the tests).
// ---------------------------------------------------------------------------

/// One source primitive after triangulation and (glTF) node transform. One
/// glTF mesh instanced by several nodes gives several RawPrimitives with the
/// same mesh/primitive ids.
struct RawPrimitive {
    uint32_t mesh = 0;        ///< SourceRef::mesh
    uint32_t primitive = 0;   ///< SourceRef::primitive
    std::vector<Vec3> vertices;
    /// Triangles in source (triangulated) order: SourceRef::triangle is the
    /// position in this list. Indices are checked < vertices.size().
    std::vector<std::array<uint32_t, 3>> triangles;
};

struct RawInput {
    std::vector<RawPrimitive> primitives;
    std::map<std::string, uint64_t> skipped_primitives;  ///< "points", "lines", ...
    /// Faces the file declares but a third-party reader refused before we saw
    /// them (OpenMesh drops faces with repeated or unparsable vertices). Each
    /// counts as one input triangle dropped for reason "rejected_by_reader", so
    /// that the totals stay honest even though the faces never reach us.
    uint64_t rejected_by_reader = 0;
};

/// glTF placements kept as instances (import_gltf with `instanced`).
struct RawPlacement {
    uint32_t node = kInvalidIndex;  ///< glTF node (kInvalidIndex: the merged identity placement)
    uint32_t mesh = 0;              ///< index into RawInstanced::meshes
    std::array<double, 12> object_to_world{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};  ///< 3x4 row-major
};

/// A glTF file whose instancing is kept: the meshes placed >= 2 times in
/// object space (ascending glTF mesh index), then, if any geometry is placed
/// once, that geometry merged in world space (last, source_mesh kInvalidIndex,
/// one identity placement).
struct RawInstanced {
    std::vector<RawInput> meshes;
    std::vector<uint32_t> source_mesh;  ///< glTF mesh per entry of `meshes` (kInvalidIndex: merged)
    std::vector<RawPlacement> placements;  ///< in node walk order, the merged identity placement last
};

/// Per-format readers. Each returns false and sets `error` (without the file
/// name prefix; import_scene adds it) on bad input.
/// import_gltf with `instanced` set: when some glTF mesh of the scene is
/// placed by more than one node, fills *instanced (out stays empty) and sets
/// *is_instanced; otherwise the file is read exactly as without it (out filled,
/// byte-identical downstream) and *is_instanced is false.
Result import_gltf(const std::string& path, const ImportOptions& options, RawInput& out,
                   std::vector<std::string>& warnings, RawInstanced* instanced = nullptr,
                   bool* is_instanced = nullptr);
Result import_openmesh(const std::string& path, const ImportOptions& options,
                                   RawInput& out,
                                   std::vector<std::string>& warnings);
Result import_draco_file(const std::string& path, RawInput& out);

/// The files an input names besides itself, which an output must never replace (cwbvhc
/// -o over a glTF's external buffer would destroy the scene's data; over a texture or an
/// OBJ's material library, the user's): a glTF's buffer and image URIs that are not data:
/// URIs (as written and percent-decoded, relative to the glTF's folder), an OBJ's
/// `mtllib` files. Best effort and never an error: an input it cannot read or parse gives
/// none (the import then reports it).
std::vector<std::string> referenced_files(const std::string& input);
/// Every file the inputs reference (referenced_files of each), at most kMaxReferencedFiles
/// in all (a hostile file may name millions; each costs a stat in check_output_not_referenced).
std::vector<std::string> referenced_files(const std::vector<std::string>& inputs);
inline constexpr size_t kMaxReferencedFiles = 65536;
std::vector<std::string> gltf_referenced_files(const std::string& path);
std::vector<std::string> obj_referenced_files(const std::string& path);

/// The whole file in one read (the readers' input; the importers used a
/// byte-by-byte stream iterator, 26 ms of the dragon's 0.1 s import).
/// kIoError: "cannot open: <why>", "is a FIFO, not a regular file" (any non-regular file
/// is refused before a byte is read), "read error: <why>".
Result read_file_bytes(const std::string& path, std::vector<uint8_t>& bytes);

/// Decodes a Draco mesh (KHR_draco_mesh_compression or a .drc file) into
/// positions and triangles. `position_id`: the Draco attribute unique id of
/// the positions, or -1 for "the POSITION attribute". Positions come back as
/// Draco's dequantized floats.
Result decode_draco_mesh(const uint8_t* data, size_t size, int position_id,
                                     std::vector<Vec3>& vertices,
                                     std::vector<std::array<uint32_t, 3>>& triangles);

/// Largest accepted coordinate magnitude: 2^125. The quantizer of the wide
/// nodes needs a power-of-two scale 2^(e-127) with e <= 254 covering the
/// extent of a box; coordinates beyond 2^125 (about 4.25e37) cannot be
/// encoded, so files with such (finite) coordinates are rejected.
inline constexpr float kMaxCoordinate = 0x1p125f;

/// Exact degeneracy test: true iff the cross product (b-a) x (c-a) is
/// exactly zero in real arithmetic, i.e. the three points are collinear or
/// coincident. Each edge component is formed in double and each cross term is
/// evaluated as an exact two-double product (fma), so the answer is exact
/// whenever the edge components are exact in double (always, unless one
/// triangle spans more than 29 binades on one axis). When an edge component
/// is not exact the triangle is reported as not degenerate (kept): we only
/// drop what is provably zero-area.
bool is_degenerate(const Vec3& a, const Vec3& b, const Vec3& c);

/// Appends `input` as input number `input_index` to `scene`: every triangle
/// counts in input_triangles; triangles with a NaN/Inf coordinate are dropped
/// ("nonfinite"), exactly zero-area ones too ("degenerate"); nothing else is
/// changed (no welding, no reordering). Vertices not referenced by a kept
/// triangle are removed, the rest keep their relative source order (so the
/// indices equal the source's when every vertex is used). Returns false (error
/// set) for a finite coordinate beyond kMaxCoordinate or a scene exceeding
/// 32-bit indices.
Result clean_and_append(const RawInput& input, uint32_t input_index, Scene& scene);

}  // namespace cwbvh::compiler
