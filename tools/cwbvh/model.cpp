// cwbvh model FILE --rays RAYS [--bvh2|--bvh2-2009] [--any] [--fast] [--warps N] [--no-postpone]
//                  [--postpone-percent P] [--postpone-with-node-work] [--no-dynamic-fetch] [--nd N] [--nw N]
//                  [--shared-entries N] [--node-instructions N] [--tri-instructions N] [--no-defer-hits]
//                  [--reference-node-test] [--check]
// Runs the CPU lock-step warp model of the GPU kernels (warp_model.h) over a ray
// file and prints SIMT efficiency figures: active lanes per node step and per
// triangle round, steps per ray, the node/triangle phase mix, spills, refills.
// --check also traces the rays with the CPU reference and counts disagreements
// (the model runs the kernel's lane code, so there should be none but ties).
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "args.h"
#include "commands.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/kernels/warp_model.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh::tool {
namespace {

void print_hist(const char* name, const uint64_t (&h)[33]) {
    uint64_t total = 0;
    for (uint64_t v : h) total += v;
    std::printf("%-16s", name);
    for (int i = 1; i <= 32; ++i) std::printf(" %4.1f", total ? 100.0 * double(h[i]) / double(total) : 0.0);
    std::printf("   (%% of steps with 1..32 lanes)\n");
}

}  // namespace

int run_model(int argc, char** argv) {
    const char* usage =
        "usage: cwbvh model FILE --rays RAYS [--bvh2|--bvh2-2009] [--any] [--fast] [--warps N] [--no-postpone] "
        "[--postpone-percent P] [--postpone-with-node-work] [--no-dynamic-fetch] [--nd N] [--nw N] [--shared-entries "
        "N] [--node-instructions N] [--tri-instructions N] [--no-defer-hits] "
        "[--reference-node-test] [--check]";
    const char* path = nullptr;
    const char* rays_path = nullptr;
    bool bvh2 = false, check = false;
    WarpModelOptions o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        uint32_t v = 0;
        auto num = [&](uint32_t lo, uint32_t hi) { return parse_u32(option_value(argc, argv, i), lo, hi, v); };
        if (a == "--rays") {
            if (!(rays_path = option_value(argc, argv, i))) return error(kExitUsage, "model: --rays needs a path");
        } else if (a == "--bvh2") {
            bvh2 = true;
        } else if (a == "--bvh2-2009") {
            bvh2 = true;
            o.bvh2_kernel = Bvh2Kernel::kWhileWhile2009;
        } else if (a == "--any") {
            o.mode = HitMode::kAny;
        } else if (a == "--fast") {
            o.test = TriangleTest::kFast;
        } else if (a == "--check") {
            check = true;
        } else if (a == "--no-postpone") {
            o.postpone = false;
        } else if (a == "--postpone-with-node-work") {
            o.postpone_needs_node_work = true;
        } else if (a == "--no-dynamic-fetch") {
            o.dynamic_fetch = false;
        } else if (a == "--no-defer-hits") {
            o.defer_hits = false;
        } else if (a == "--reference-node-test") {
            o.fast_node_test = false;
        } else if (a == "--warps") {
            if (!num(1, 1u << 20)) return error(kExitUsage, "model: --warps needs an integer in [1, 1048576]");
            o.warps = v;
        } else if (a == "--postpone-percent") {
            if (!num(0, 100)) return error(kExitUsage, "model: --postpone-percent needs an integer in [0, 100]");
            o.postpone_percent = int(v);
        } else if (a == "--nd") {
            if (!num(0, 32)) return error(kExitUsage, "model: --nd needs an integer in [0, 32]");
            o.fetch_nd = int(v);
        } else if (a == "--nw") {
            if (!num(1, 1024)) return error(kExitUsage, "model: --nw needs an integer in [1, 1024]");
            o.fetch_nw = int(v);
        } else if (a == "--node-instructions") {
            if (!num(1, 100000)) return error(kExitUsage, "model: --node-instructions needs an integer in [1, 100000]");
            o.node_instructions = o.bvh2_node_instructions = double(v);
        } else if (a == "--tri-instructions") {
            if (!num(1, 100000)) return error(kExitUsage, "model: --tri-instructions needs an integer in [1, 100000]");
            o.tri_instructions = double(v);
        } else if (a == "--shared-entries") {
            if (!num(0, 64)) return error(kExitUsage, "model: --shared-entries needs an integer in [0, 64]");
            o.shared_stack_entries = int(v);
        } else if (a.size() > 1 && a[0] == '-') {
            return error(kExitUsage, ("model: unknown option " + a).c_str());
        } else if (path) {
            return error(kExitUsage, "model: expects exactly one FILE");
        } else {
            path = argv[i];
        }
    }
    if (!path || !rays_path) return error(kExitUsage, usage);

    // With the two-level sections, so that a two-level file gets this verb's own message (the
    // loader's names the API masks a library caller sets).
    const uint32_t mask = kMaskNodes | kMaskTriangles | kMaskTwoLevel | (bvh2 ? kMaskBvh2 : 0u);
    auto file = File::open(path, {true, mask});
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    if (file->is_two_level())
        return error(kExitBadInput, (std::string(path) + ": a two-level file (instanced glTF): the warp model "
                                     "runs single-level trees; compile with cwbvhc --flatten")
                                        .c_str());
    if (bvh2 && file->bvh2().empty())
        return error(kExitBadInput, (std::string(path) + ": no BVH2 section (compile with --keep-sbvh)").c_str());
    std::vector<Ray> rays;
    if (const Result r = read_ray_file(rays_path, rays); !r.ok()) return error(kExitBadInput, r.message.c_str());

    std::vector<Hit> hits(rays.size());
    const auto tris = file->triangles();
    WarpModelStats s;
    if (bvh2) {
        const auto n = file->bvh2();
        s = model_bvh2_warps(n.data(), n.size(), tris.data(), tris.size(), rays.data(), hits.data(), rays.size(), o);
    } else {
        const auto n = file->nodes();
        s = model_cwbvh_warps(n.data(), n.size(), tris.data(), tris.size(), rays.data(), hits.data(), rays.size(), o);
    }

    const double n = double(s.rays ? s.rays : 1);
    std::printf("model            %s (%s, %s), %u warps, postpone %s (%d%%), fetch %s (Nd %d, Nw %d)\n",
                bvh2 ? (o.bvh2_kernel == Bvh2Kernel::kAkl2012 ? "bvh2 (Aila-Karras-Laine 2012)"
                                                               : "bvh2 (Aila-Laine 2009 while-while)")
                     : "cwbvh", o.mode == HitMode::kAny ? "any-hit" : "closest-hit",
                o.test == TriangleTest::kFast ? "fast test" : "watertight test", o.warps,
                o.postpone && !bvh2 ? "on" : "off", o.postpone_percent,
                bvh2 ? (o.bvh2_kernel == Bvh2Kernel::kAkl2012 ? "below 20 busy lanes" : "whole warp")
                     : (o.dynamic_fetch ? "dynamic" : "whole warp"),
                o.fetch_nd, o.fetch_nw);
    std::printf("rays             %llu (hits %llu, invalid %llu)\n", (unsigned long long)s.rays,
                (unsigned long long)s.hits, (unsigned long long)s.invalid_rays);
    std::printf("nodes/ray        %.2f\n", double(s.lane_node_steps) / n);
    if (s.lane_node_steps != 0)
        std::printf("fast node steps  %.2f%% (intersect_node_fast; the rest: intersect_node)\n",
                    100.0 * double(s.lane_fast_node_steps) / double(s.lane_node_steps));
    std::printf("triangles/ray    %.2f\n", double(s.lane_tri_tests) / n);
    std::printf("lanes/node step  %.2f\n", s.lanes_per_node_step());
    std::printf("lanes/tri step   %.2f\n", s.lanes_per_tri_step());
    std::printf("lanes/iteration  %.2f (lanes holding a ray)\n", s.lanes_per_iteration());
    std::printf("lanes/instr est  %.2f (weights node %.0f, tri %.0f, control %.0f)\n",
                s.estimated_lanes_per_instruction, bvh2 ? o.bvh2_node_instructions : o.node_instructions,
                o.tri_instructions, o.control_instructions);
    std::printf("instr/ray est    %.0f (warp instructions issued per ray, same weights)\n", s.instructions_per_ray());
    std::printf("warp steps/ray   %.2f (x32 lanes; node %llu, triangle %llu: %.1f%% triangle)\n", s.steps_per_ray(),
                (unsigned long long)s.warp_node_steps, (unsigned long long)s.warp_tri_steps,
                100.0 * s.tri_step_share());
    std::printf("refills          %llu (%.2f per 32 rays)\n", (unsigned long long)s.refills,
                32.0 * double(s.refills) / n);
    std::printf("postponed groups %llu (%.3f per ray)\n", (unsigned long long)s.postponed, double(s.postponed) / n);
    if (!bvh2 && o.test == TriangleTest::kWatertight) {
        // The watertight test's double-precision path: how often a warp runs it, in its
        // rounds and, with deferred hits (cwbvh_lane.h, test_triangle_deferred; the kernel's
        // way; --no-defer-hits: the kernel before issue 18's deferral), at refill time.
        std::printf("double path      %llu tests (%.3f per ray) in %llu rounds (%.3f per ray, %.1f%% of rounds)\n",
                    (unsigned long long)s.lane_whole_tests, double(s.lane_whole_tests) / n,
                    (unsigned long long)s.warp_whole_rounds, double(s.warp_whole_rounds) / n,
                    s.warp_tri_steps ? 100.0 * double(s.warp_whole_rounds) / double(s.warp_tri_steps) : 0.0);
        if (o.defer_hits)
            std::printf("deferred hits    %llu (%.3f per ray), %llu finished in rounds, %llu at %llu refills "
                        "(%.3f per ray)%s\n",
                        (unsigned long long)s.lane_deferred_hits, double(s.lane_deferred_hits) / n,
                        (unsigned long long)s.lane_prev_finished, (unsigned long long)s.lane_finalized,
                        (unsigned long long)s.warp_finalize_steps, double(s.warp_finalize_steps) / n,
                        s.finalize_failures ? "; FINALIZE FAILURES (a bug)" : "");
    }
    std::printf("spilled pushes   %llu (%.4f per ray), deepest stack %llu\n", (unsigned long long)s.spilled_pushes,
                double(s.spilled_pushes) / n, (unsigned long long)s.max_stack);
    if (s.worst_ray_nodes + s.worst_ray_tris > 0)  // the CWBVH model keeps it
        std::printf("worst ray        %llu: %u nodes, %u triangles (the launch lasts as long as its slowest ray; "
                    "mean %.2f, %.2f)\n",
                    (unsigned long long)s.worst_ray_id, s.worst_ray_nodes, s.worst_ray_tris,
                    double(s.lane_node_steps) / n, double(s.lane_tri_tests) / n);
    if (s.stack_overflows || s.bad_indices)
        std::printf("stack overflows  %llu\nbad indices      %llu\n", (unsigned long long)s.stack_overflows,
                    (unsigned long long)s.bad_indices);
    print_hist("node lanes", s.node_lane_hist);
    print_hist("tri lanes", s.tri_lane_hist);

    if (check) {
        std::vector<Hit> ref(rays.size());
        CpuTraceOptions co;
        co.mode = o.mode;
        co.test = o.test;
        if (bvh2) {
            const auto b = file->bvh2();
            trace_bvh2_cpu(b.data(), b.size(), tris.data(), tris.size(), rays.data(), ref.data(), rays.size(), co);
        } else {
            const auto nodes = file->nodes();
            trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), rays.data(), ref.data(),
                            rays.size(), co);
        }
        uint64_t bad = 0, ties = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            const bool hm = hits[i].prim != kMissPrim, hr = ref[i].prim != kMissPrim;
            if (hm != hr || (hm && o.mode == HitMode::kClosest && hits[i].t != ref[i].t)) {
                ++bad;
            } else if (hm && o.mode == HitMode::kClosest && hits[i].prim != ref[i].prim) {
                ++ties;
            }
        }
        std::printf("check            %llu disagreements with the CPU reference, %llu ties (same t, other triangle)\n",
                    (unsigned long long)bad, (unsigned long long)ties);
        if (bad) return kExitBadInput;
    }
    return (s.stack_overflows || s.bad_indices) ? kExitBadInput : kExitOk;
}

}  // namespace cwbvh::tool
