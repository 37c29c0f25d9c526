// Last two phases of cwbvhc: encode the wide tree into file sections, then
// write them through format/'s Writer.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/encode.h"
#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

struct EmitInput {
    const CompileOptions* options = nullptr;
    const Scene* scene = nullptr;
    const BinaryBvh* binary = nullptr;   ///< only needed (and only set) with options->keep_sbvh
    uint64_t references = 0;             ///< binary leaves (BILD)
    uint64_t binary_nodes = 0;           ///< binary nodes (BILD)
    const WideBvh* wide = nullptr;
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
    uint64_t wide_nodes = 0;
    uint32_t wide_depth = 0;   ///< levels of NODE (root = 1)
    uint32_t bvh2_depth = 0;   ///< levels of BV2L incl. leaves (only with keep_sbvh)
    double avg_children = 0;
    uint32_t max_leaf_triangles = 0;
    double sah_wide = 0;
};

/// Quantizes and lays out the tree (NODE, TRIS, optional BV2L), verifies it
/// when options->verify, and fills the BILD/BNDS/SRCN/PMAP payloads.
[[nodiscard]] bool encode_scene(const EmitInput& in, EmitResult& out, std::string& error);

/// Writes the file atomically. `bytes` gets (section name, payload bytes) in file order.
[[nodiscard]] bool write_scene(const EmitInput& in, const EmitResult& encoded,
                               std::vector<std::pair<std::string, uint64_t>>& bytes, uint64_t& file_bytes,
                               std::string& error);

}  // namespace cwbvh::compiler
