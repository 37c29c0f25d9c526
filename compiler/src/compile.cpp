// The compile pipeline: each phase is one call into its own module; this file
// only sequences them, times them and collects statistics.
#include <sys/resource.h>

#include <chrono>
#include <string>

#include "cwbvh/compiler/auction.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/emit.h"
#include "cwbvh/compiler/import.h"
#include "cwbvh/compiler/model.h"
#include "cwbvh/compiler/sah_report.h"

namespace cwbvh::compiler {
namespace {

uint64_t peak_rss_bytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return uint64_t(usage.ru_maxrss) * 1024u;  // Linux reports KiB
}

/// Times one phase and reports it through the callback.
class PhaseTimer {
public:
    PhaseTimer(CompileStats& stats, const PhaseCallback& cb) : stats_(stats), cb_(cb) {}
    template <class F>
    bool run(const std::string& name, F&& body) {
        if (cb_) cb_(name, false, 0.0);
        const auto start = std::chrono::steady_clock::now();
        const bool ok = body();
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        stats_.seconds.emplace_back(name, seconds);
        stats_.peak_rss_after.emplace_back(name, peak_rss_bytes());
        if (cb_ && ok) cb_(name, true, seconds);
        return ok;
    }

private:
    CompileStats& stats_;
    const PhaseCallback& cb_;
};

}  // namespace

bool compile(const CompileOptions& options, CompileStats& stats, std::string& error, const PhaseCallback& on_phase) {
    PhaseTimer timer(stats, on_phase);

    Scene scene;
    if (!timer.run("import", [&] {
            ImportOptions import_options;
            return import_scene(options.inputs, import_options, scene, error, stats.warnings);
        }))
        return false;
    stats.input_triangles = scene.input_triangles;
    stats.dropped_triangles = scene.dropped;
    stats.skipped_primitives = scene.skipped_primitives;
    stats.triangles = scene.triangle_count();
    if (scene.triangle_count() == 0) {
        error = options.inputs.front() + (options.inputs.size() > 1 ? " (and others)" : "") +
                ": no triangles left to compile";
        return false;
    }

    BinaryBvh binary;
    SbvhConfig sbvh_config;
    sbvh_config.split_alpha = options.split_alpha;
    sbvh_config.threads = options.threads;
    if (!timer.run(options.builder == kBuilderEmbree ? "embree" : "sbvh", [&] {
            return options.builder == kBuilderEmbree ? build_embree(scene, sbvh_config, binary, error)
                                                     : build_sbvh(scene, sbvh_config, binary, error);
        }))
        return false;
    stats.references = binary.references;
    stats.spatial_splits = binary.spatial_splits;
    stats.binary_nodes = binary.nodes.size();

    CollapseConfig collapse_config;
    collapse_config.kind = options.collapse;
    collapse_config.cost_prim = options.collapse_cost_prim;
    stats.sah_binary = report_sah_binary(binary);

    WideBvh wide;
    if (!timer.run("collapse", [&] { return collapse_wide(binary, collapse_config, wide, error); })) return false;
    if (!timer.run("slots", [&] {
            assign_slots(wide);
            return true;
        }))
        return false;

    EmitInput emit;
    emit.options = &options;
    emit.scene = &scene;
    emit.binary = &binary;
    emit.wide = &wide;
    emit.collapse = &collapse_config;
    emit.sbvh = &sbvh_config;
    emit.sah_binary = stats.sah_binary;
    EmitResult emitted;
    if (!timer.run("encode", [&] { return encode_scene(emit, emitted, error); })) return false;
    stats.wide_nodes = emitted.wide_nodes;
    stats.wide_depth = emitted.wide_depth;
    stats.avg_children = emitted.avg_children;
    stats.max_leaf_triangles = emitted.max_leaf_triangles;
    stats.sah_wide = emitted.sah_wide;
    if (!timer.run("write", [&] { return write_scene(emit, emitted, stats.bytes, stats.file_bytes, error); }))
        return false;

    stats.peak_rss_bytes = peak_rss_bytes();
    return true;
}

}  // namespace cwbvh::compiler
