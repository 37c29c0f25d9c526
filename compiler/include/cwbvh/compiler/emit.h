// Last two steps of the core (core.h): encode the wide tree into file sections,
// then hand them to format/'s one section list (add_scene_sections) and write.
#pragma once

#include <cstdint>
#include <span>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/compiler/encode.h"
#include "cwbvh/compiler/model.h"
#include "cwbvh/format/scene_data.h"

namespace cwbvh::compiler {

struct SbvhConfig;

/// The optional binary BVH section.
enum class Bvh2Section {
    kNone,
    kBvh2,        ///< BVH2 (format 1.0): the whole binary tree, one record per leaf
    kLeafRanges,  ///< BV2L (format 1.1): cut at the wide leaves (cwbvhc --keep-sbvh)
};

/// Which optional sections are written, and whether the encoding is checked.
struct EmitOptions {
    BuilderKind builder = kBuilderSbvh;     ///< the builder of the binary tree, recorded in BILD
    Bvh2Section bvh2 = Bvh2Section::kNone;  ///< BVH2 / BV2L section
    bool keep_mesh = false;                 ///< VERT/INDX sections
    bool verify = true;                     ///< decode every node and check containment and PMAP
};

struct EmitInput {
    const EmitOptions* options = nullptr;
    const Scene* scene = nullptr;
    const BinaryBvh* binary = nullptr;   ///< only needed (and only set) with options->bvh2 != kNone
    uint64_t references = 0;             ///< binary leaves (BILD)
    uint64_t binary_nodes = 0;           ///< binary nodes (BILD)
    const WideBvh* wide = nullptr;       ///< null only for a scene without triangles
    /// Called once the wide tree's exact boxes (its binary tree) are no longer
    /// read: after the nodes are quantized and their boxes verified, before
    /// the triangle records are allocated (optional; the core frees the
    /// binary tree there unless a BVH2/BV2L section needs it).
    std::function<void()> boxes_done;
    const CollapseConfig* collapse = nullptr;
    const SbvhConfig* sbvh = nullptr;
    double sah_binary = 0;
};

struct EmitResult {
    EncodedTree tree;
    BuildInfo build_info{};
    SceneBounds bounds{};
    std::vector<uint8_t> source_names;  ///< SRCN payload
    std::vector<SourceRange> source_ranges;  ///< PMAP payload: Scene::sources as runs
    bool bvh2_leaf_ranges = false;      ///< tree.bvh2 is BV2L (else BVH2, if not empty)
    bool keep_mesh = false;             ///< write VERT/INDX from the scene
    uint64_t wide_nodes = 0;
    uint32_t wide_depth = 0;   ///< levels of NODE (root = 1)
    uint32_t bvh2_depth = 0;   ///< levels of BVH2/BV2L incl. leaves (only with a binary BVH section)
    double avg_children = 0;
    uint32_t max_leaf_triangles = 0;
    double sah_wide = 0;
};

/// BILD's build parameters and import counts (everything before `triangles`), one
/// place for single-level files (emit.cpp) and two-level ones (two_level.cpp).
BuildInfo build_info_head(uint32_t builder, const SbvhConfig& sbvh, const CollapseConfig& collapse,
                          uint64_t input_triangles, const std::map<std::string, uint64_t>& dropped,
                          const std::map<std::string, uint64_t>& skipped_primitives);

/// The bounding box of the scene's stored triangles (empty box for no triangles):
/// the BNDS section and the root area of the SAH report.
Aabb scene_box(const Scene& scene);

/// Turns scene.sources into scene.source_ranges (the PMAP runs) and frees the
/// per-triangle map. With `verify`, every triangle's run is decoded back and
/// compared first (kInternal on a mismatch). A scene whose ranges are made
/// already is left as it is.
Result make_scene_source_ranges(Scene& scene, bool verify);

/// Quantizes and lays out the tree (NODE, TRIS, optional BVH2/BV2L), verifies it
/// when options->verify, and fills the BILD/BNDS/SRCN/PMAP payloads. A scene
/// without triangles (wide == nullptr) gives the empty scene of spec 3.2: one
/// root without used slots, no TRIS, BNDS zeros.
Result encode_scene(const EmitInput& in, EmitResult& out);

/// The file's sections: NODE, TRIS, PMAP, BNDS, BILD and SRCN always, BVH2/BV2L and
/// VERT/INDX as chosen. Spans into `scene` and `encoded`.
SceneSections scene_sections(const Scene& scene, const EmitResult& encoded);

/// Lays out and writes `writer`'s sections atomically to `path`; `bytes` gets
/// (section name, payload bytes) in file order.
Result write_with(const Writer& writer, const std::string& path, std::vector<std::pair<std::string, uint64_t>>& bytes,
                  uint64_t& file_bytes);

/// Writes the file atomically to `path`. `bytes` gets (section name, payload bytes) in file order.
Result write_scene(const Scene& scene, const EmitResult& encoded, const std::string& path,
                               std::vector<std::pair<std::string, uint64_t>>& bytes, uint64_t& file_bytes);

/// The same file's bytes in memory.
Result scene_bytes(const Scene& scene, const EmitResult& encoded, std::vector<uint8_t>& out);

}  // namespace cwbvh::compiler
