// The whole compile pipeline behind `cwbvhc`: import -> SBVH -> collapse ->
// slots -> quantize/encode -> write. main.cpp only parses arguments.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"
#include "cwbvh/compiler/build.h"

namespace cwbvh::compiler {

struct Progress;

struct CompileOptions {
    std::vector<std::string> inputs;
    std::string output;
    int threads = 0;                      ///< 0: all cores; output bytes never depend on it
    BuilderKind builder = kBuilderSbvh;
    CollapseKind collapse = kCollapseOptimal;
    float split_alpha = kDefaultSplitAlpha;  ///< SBVH overlap threshold (Stich et al. 2009; see build.h)
    float max_reference_growth = 0.15f;   ///< SBVH reference budget: references <= (1 + x) * triangles (see SbvhConfig)
    float collapse_cost_prim = 0.3f;      ///< C_prim of the collapse DP (C_node = 1), stored in BILD
    bool keep_sbvh = false;               ///< write the optional BV2L section (binary BVH with leaf ranges)
    bool keep_mesh = false;               ///< write the optional VERT/INDX sections
    bool allow_parent_uris = false;       ///< glTF: let buffer URIs reach out of the input's folder ('..')
    bool verify = true;                   ///< decode every node and check containment before writing
    /// Single-level file always (today's file). Off: a glTF input in which
    /// some mesh is placed by more than one node gives a two-level file
    /// (format 1.2: MESH/INST/TLAS; issue 19's policy in import.h).
    /// builder embree, keep_sbvh and keep_mesh imply it (single-level features).
    bool flatten = false;
};

/// Everything `--stats-json` reports.
struct CompileStats {
    uint64_t input_triangles = 0;
    std::map<std::string, uint64_t> dropped_triangles;
    std::map<std::string, uint64_t> skipped_primitives;
    uint64_t triangles = 0;               ///< stored (distinct) triangles
    bool two_level = false;               ///< a two-level file was written
    uint64_t meshes = 0;                  ///< two-level: bottom levels (MESH records)
    uint64_t instances = 0;               ///< two-level: INST records
    uint64_t instanced_triangles = 0;     ///< triangles once every instance is expanded (= triangles if single-level)
    uint64_t top_nodes = 0;               ///< two-level: TLAS nodes
    uint32_t top_depth = 0;               ///< two-level: TLAS levels
    /// Two-level: the core's phases per mesh (sbvh, collapse, slots, encode),
    /// seconds summed over the meshes (CPU seconds; they run in parallel).
    std::vector<std::pair<std::string, double>> mesh_phase_seconds;
    uint64_t references = 0;
    uint64_t spatial_splits = 0;
    uint64_t binary_nodes = 0;
    uint64_t wide_nodes = 0;
    uint32_t wide_depth = 0;
    double avg_children = 0;
    uint32_t max_leaf_triangles = 0;
    double sah_binary = 0;
    double sah_wide = 0;
    std::vector<std::pair<std::string, uint64_t>> bytes;     ///< section -> bytes, file order
    std::vector<std::pair<std::string, double>> seconds;     ///< phase -> seconds, run order
    uint64_t file_bytes = 0;
    uint64_t peak_rss_bytes = 0;
    /// Peak RSS of the process so far, sampled at the end of each phase (shows which phase peaks).
    std::vector<std::pair<std::string, uint64_t>> peak_rss_after;
    /// Resident set size at the end of each phase (what the next phase starts from).
    std::vector<std::pair<std::string, uint64_t>> rss_after;
    std::vector<std::string> warnings;
};

/// Called when a phase starts (done=false) and ends (done=true), on the thread that runs
/// compile(). It cancels the compile by throwing: the exception leaves compile() at once and no
/// later phase runs, so a throw before the end of the "write" phase (done=true) writes nothing
/// and leaves a file already at the output path as it was (the writer's AtomicOutput).
using PhaseCallback = std::function<void(const std::string& phase, bool done, double seconds)>;

/// Runs the pipeline. On bad input returns a failed Result whose message is one
/// line naming the file and what is wrong.
/// `progress` (optional, progress.h) is reset before each phase's start callback to the
/// units that phase counts (sbvh: triangles, collapse: binary nodes, slots: wide nodes;
/// two-level files: meshes counts the distinct triangles, assemble/instances/tlas 0;
/// 0 for import, embree, encode and write, which are not counted) and advanced by the
/// phase from its worker threads; a counted phase ends with done == total. It is only
/// ever written: the output file is the same with or without it.
Result compile(const CompileOptions& options, CompileStats& stats, const PhaseCallback& on_phase = {},
              Progress* progress = nullptr);

/// JSON for --stats-json (keys documented in README).
std::string stats_to_json(const CompileStats& stats);

/// Human summary table printed at the end of a compile.
std::string stats_to_table(const CompileStats& stats);

}  // namespace cwbvh::compiler
