// compile_binary / compile_scene: the core's sequence, one call per stage.
#include "cwbvh/compiler/core.h"

#include "cwbvh/compiler/auction.h"
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/sah_report.h"

namespace cwbvh::compiler {
namespace {

bool run_phase(const PhaseRunner& run, const char* name, uint64_t units, const std::function<bool()>& body) {
    return run ? run(name, units, body) : body();
}

}  // namespace

Result compile_binary(const Scene& scene, BinaryBvh& binary, const CoreOptions& options, EmitResult& out,
                      const PhaseRunner& run, Progress* progress) {
    EmitInput emit;
    emit.options = &options.emit;
    emit.scene = &scene;
    emit.references = binary.references;
    emit.binary_nodes = binary.nodes.size();
    emit.collapse = &options.collapse;
    emit.sbvh = &options.sbvh;
    emit.sah_binary = report_sah_binary(binary);

    WideBvh wide;
    Result r;
    CollapseConfig collapse = options.collapse;
    collapse.binary_leaf_refs = options.emit.bvh2 != Bvh2Section::kNone;  // only the BVH2 encoder reads them
    if (!run_phase(run, "collapse", binary.nodes.size(), [&] {
            r = collapse_wide(binary, collapse, wide, progress);
            return r.ok();
        }))
        return r;
    if (!run_phase(run, "slots", wide.nodes.size(), [&] {
            assign_slots(wide, progress);
            return true;
        }))
        return r;

    // The binary tree holds the wide tree's exact boxes until the nodes are
    // quantized; then it is only needed for the optional BVH2/BV2L section.
    // Without it, it is the largest structure alive (32 bytes per node): freed
    // before the triangle records are allocated.
    const bool keep_binary = options.emit.bvh2 != Bvh2Section::kNone;
    if (!keep_binary) emit.boxes_done = [&binary] { BinaryBvh{}.nodes.swap(binary.nodes); };
    emit.binary = keep_binary ? &binary : nullptr;
    emit.wide = &wide;
    run_phase(run, "encode", 0, [&] {
        r = encode_scene(emit, out);
        return r.ok();
    });
    return r;
}

Result compile_scene(const Scene& scene, const CoreOptions& options, EmitResult& out) {
    if (scene.triangle_count() == 0) {
        EmitInput emit;
        emit.options = &options.emit;
        emit.scene = &scene;
        emit.collapse = &options.collapse;
        emit.sbvh = &options.sbvh;
        return encode_scene(emit, out);
    }
    BinaryBvh binary;
    if (Result r = build_sbvh(scene, options.sbvh, binary); !r.ok()) return r;
    return compile_binary(scene, binary, options, out);
}

}  // namespace cwbvh::compiler
