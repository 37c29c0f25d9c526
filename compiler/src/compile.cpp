// The compile pipeline of cwbvhc: import (front end), binary builder (SBVH or
// Embree), then the core (core.h) from the binary tree to the written file; this
// file only sequences them, times them and collects statistics.
#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <tbb/task_arena.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/core.h"
#include "cwbvh/compiler/emit.h"
#include "cwbvh/compiler/import.h"
#include "cwbvh/compiler/model.h"
#include "cwbvh/format/file_io.h"
#include "cwbvh/compiler/progress.h"
#include "cwbvh/compiler/two_level.h"

namespace cwbvh::compiler {
namespace {

uint64_t peak_rss_bytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return uint64_t(usage.ru_maxrss) * 1024u;  // Linux reports KiB
}

/// Resident set size now (second field of /proc/self/statm, in pages); 0 if unreadable.
uint64_t rss_now_bytes() {
    FILE* f = std::fopen("/proc/self/statm", "r");
    if (!f) return 0;
    unsigned long long size = 0, resident = 0;
    const int got = std::fscanf(f, "%llu %llu", &size, &resident);
    std::fclose(f);
    return got == 2 ? uint64_t(resident) * uint64_t(sysconf(_SC_PAGESIZE)) : 0;
}

/// Hands freed heap pages back to the OS. The builders free large,
/// fragmented allocations made on TBB worker threads (their own malloc
/// arenas), which later phases on the main thread cannot reuse; without this
/// they stay resident and add to the peak.
void release_free_heap() { malloc_trim(0); }

/// Times one phase and reports it through the callback and the progress channel.
class PhaseTimer {
public:
    PhaseTimer(CompileStats& stats, const PhaseCallback& cb, Progress* progress)
        : stats_(stats), cb_(cb), progress_(progress) {}
    /// `units`: what the phase adds to the progress channel in all (0: not counted).
    template <class F>
    bool run(const std::string& name, uint64_t units, F&& body) {
        if (progress_) progress_->reset(units);  // before the callback: a display it wakes sees the new total
        if (cb_) cb_(name, false, 0.0);
        const auto start = std::chrono::steady_clock::now();
        const bool ok = body();
        // Whatever the phase freed (the importers' model, the builder's
        // reference lists, ...) goes back to the OS before the next one.
        release_free_heap();
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        stats_.seconds.emplace_back(name, seconds);
        stats_.peak_rss_after.emplace_back(name, peak_rss_bytes());
        stats_.rss_after.emplace_back(name, rss_now_bytes());
        if (cb_ && ok) cb_(name, true, seconds);
        return ok;
    }

private:
    CompileStats& stats_;
    const PhaseCallback& cb_;
    Progress* progress_;
};

/// The core settings cwbvhc's options choose.
CoreOptions core_options(const CompileOptions& options) {
    CoreOptions core;
    core.sbvh.split_alpha = options.split_alpha;
    core.sbvh.threads = options.threads;
    core.sbvh.max_reference_growth = options.max_reference_growth;
    core.collapse.kind = options.collapse;
    core.collapse.cost_prim = options.collapse_cost_prim;
    core.emit.builder = options.builder;
    core.emit.bvh2 = options.keep_sbvh ? Bvh2Section::kLeafRanges : Bvh2Section::kNone;
    core.emit.keep_mesh = options.keep_mesh;
    core.emit.verify = options.verify;
    return core;
}

/// Two-level file (issue 19): every distinct mesh through the core, the top
/// level over the instances, then the write.
Result compile_two_level_phases(const CompileOptions& options, InstancedScene& scene, PhaseTimer& timer,
                                CompileStats& stats, Progress* progress) {
    const std::string& file = options.inputs.front();
    Result r;
    for (Scene& mesh : scene.meshes)
        if (r = make_scene_source_ranges(mesh, options.verify); !r.ok()) return r;
    stats.two_level = true;
    stats.input_triangles = scene.input_triangles;
    stats.dropped_triangles = scene.dropped;
    stats.skipped_primitives = scene.skipped_primitives;
    stats.triangles = scene.distinct_triangles();
    stats.instanced_triangles = scene.instanced_triangles();
    stats.meshes = scene.meshes.size();
    stats.instances = scene.placements.size();
    const PhaseRunner run = [&](const std::string& name, uint64_t units, const std::function<bool()>& body) {
        return timer.run(name, units, body);
    };
    TwoLevelResult result;
    if (r = compile_two_level(scene, core_options(options), file, result, run, progress); !r.ok()) return r;
    InstancedScene{}.meshes.swap(scene.meshes);  // the triangles are in the records now
    stats.references = result.references;
    stats.spatial_splits = result.spatial_splits;
    stats.binary_nodes = result.binary_nodes;
    stats.sah_binary = result.sah_binary;
    stats.wide_nodes = result.nodes.size();
    stats.wide_depth = result.wide_depth;
    stats.avg_children = result.avg_children;
    stats.max_leaf_triangles = result.max_leaf_triangles;
    stats.sah_wide = result.sah_wide;
    stats.top_nodes = result.tlas.size();
    stats.top_depth = result.tlas_depth;
    stats.mesh_phase_seconds = result.mesh_phase_seconds;
    if (!timer.run("write", 0, [&] {
            r = write_two_level(result, options.output, stats.bytes, stats.file_bytes);
            return r.ok();
        }))
        return r;
    stats.peak_rss_bytes = peak_rss_bytes();
    return Result::success();
}

Result compile_phases(const CompileOptions& options, CompileStats& stats, const PhaseCallback& on_phase,
                      Progress* progress) {
    // The output replaces no input and no file an input names (a glTF's buffers and images, an
    // OBJ's material libraries): checked before anything is read (cwbvhc and Python alike).
    if (Result r = check_output_path(options.output, options.inputs); !r.ok()) return r;
    if (Result r = check_output_not_referenced(options.output, referenced_files(options.inputs)); !r.ok()) return r;
    PhaseTimer timer(stats, on_phase, progress);

    Scene scene;
    InstancedScene instanced;
    bool two_level = false;
    Result r;
    if (!timer.run("import", 0, [&] {
            ImportOptions import_options;
            import_options.allow_parent_uris = options.allow_parent_uris;
            // Embree, BV2L and VERT/INDX are single-level features: they imply --flatten.
            const bool flatten = options.flatten || options.builder != kBuilderSbvh || options.keep_sbvh ||
                                 options.keep_mesh;
            r = flatten ? import_scene(options.inputs, import_options, scene, stats.warnings)
                                : import_scene_instanced(options.inputs, import_options, scene, instanced, two_level,
                                                         stats.warnings);
            return r.ok();
        }))
        return r;
    if (two_level) return compile_two_level_phases(options, instanced, timer, stats, progress);
    // The per-triangle source map becomes PMAP runs now, not at the end: it
    // would be alive through the SBVH and collapse peaks (16 bytes per triangle).
    if (r = make_scene_source_ranges(scene, options.verify); !r.ok()) return r;
    stats.input_triangles = scene.input_triangles;
    stats.dropped_triangles = scene.dropped;
    stats.skipped_primitives = scene.skipped_primitives;
    stats.triangles = scene.triangle_count();
    stats.instanced_triangles = stats.triangles;
    if (scene.triangle_count() == 0) {
        return Result::fail(Status::kBadInput, 0,
                            options.inputs.front() + (options.inputs.size() > 1 ? " (and others)" : "") +
                                ": no triangles left to compile");
    }

    BinaryBvh binary;
    SbvhConfig sbvh_config;
    sbvh_config.split_alpha = options.split_alpha;
    sbvh_config.threads = options.threads;
    sbvh_config.max_reference_growth = options.max_reference_growth;
    const bool embree = options.builder == kBuilderEmbree;
    if (!timer.run(embree ? "embree" : "sbvh", embree ? 0 : scene.triangle_count(), [&] {
            r = embree ? build_embree(scene, sbvh_config, binary) : build_sbvh(scene, sbvh_config, binary, progress);
            return r.ok();
        }))
        return r;
    stats.references = binary.references;
    stats.spatial_splits = binary.spatial_splits;
    stats.binary_nodes = binary.nodes.size();

    // Everything from the binary tree on is the core's (core.h).
    CoreOptions core = core_options(options);
    const PhaseRunner run = [&](const std::string& name, uint64_t units, const std::function<bool()>& body) {
        return timer.run(name, units, body);
    };
    EmitResult emitted;
    if (r = compile_binary(scene, binary, core, emitted, run, progress); !r.ok()) return r;
    stats.sah_binary = emitted.build_info.sah_binary;
    stats.wide_nodes = emitted.wide_nodes;
    stats.wide_depth = emitted.wide_depth;
    stats.avg_children = emitted.avg_children;
    stats.max_leaf_triangles = emitted.max_leaf_triangles;
    stats.sah_wide = emitted.sah_wide;
    if (!timer.run("write", 0, [&] {
            r = write_scene(scene, emitted, options.output, stats.bytes, stats.file_bytes);
            return r.ok();
        }))
        return r;

    stats.peak_rss_bytes = peak_rss_bytes();
    return Result::success();
}

}  // namespace

Result compile(const CompileOptions& options, CompileStats& stats, const PhaseCallback& on_phase,
              Progress* progress) {
    if (options.threads <= 0) return compile_phases(options, stats, on_phase, progress);
    // Every parallel phase (SBVH, slots, ...) runs with at most `threads` threads.
    tbb::task_arena arena(options.threads);
    Result r;
    arena.execute([&] { r = compile_phases(options, stats, on_phase, progress); });
    return r;
}

}  // namespace cwbvh::compiler
