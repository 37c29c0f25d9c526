// cwbvh trace FILE --rays RAYS [--hits HITS] [--any] [--fast] [--bvh2]
//                  [--cpu | --gpu] [--threads N] [--repeat K]
//                  [--no-defer-hits] [--reference-node-test] [--postpone-percent P]
// Traces a ray file against a compiled scene and prints throughput and work
// counters; optionally writes the hit file (spec/rays.md).
//
// Backends: --cpu (default) runs the shared traversal (traverse.h) on std::threads.
// --gpu runs the CUDA kernels through cwbvh_gpu_trace (gpu_trace.h).
// A two-level file (format 1.2) is traced by traverse_two_level.h (CPU) or the
// two-level kernel (GPU); its hit file holds the instance of each hit (hit file 1.1).
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "args.h"
#include "commands.h"
#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/loader/loader.h"
#include "cwbvh/kernels/two_level_file.h"

namespace cwbvh::tool {
namespace {

struct TraceRequest {
    bool any = false;
    bool fast = false;
    CwbvhKernelOptions ab;  ///< the CWBVH kernel's A/B options (--gpu only)
    bool bvh2 = false;
    unsigned threads = 0;
};

/// Traces `rays` on the GPU (cwbvh_gpu_trace; in a build without CUDA it
/// reports why there is no GPU path) and fills `stats` (seconds = median
/// kernel time, so Mrays/s is the kernel's rate, excluding transfers).
bool trace_gpu(const File& file, const std::vector<Ray>& rays, std::vector<Hit>& hits,
               std::vector<uint32_t>& instances, const TraceRequest& r, CpuTraceStats& stats, std::string& err) {
    GpuTraceOptions o;
    static_cast<CwbvhKernelOptions&>(o) = r.ab;
    o.any = r.any;
    o.kernel = r.bvh2 ? GpuKernel::kBvh2 : GpuKernel::kCwbvh;
    o.test = r.fast ? TriangleTest::kFast : TriangleTest::kWatertight;
    Expected<GpuTraceResult> traced = trace_on_gpu(
        file, rays.data(), hits.data(), instances.empty() ? nullptr : instances.data(), rays.size(), o);
    if (!traced.ok()) {
        err = "trace: --gpu: " + traced.error().message;
        return false;
    }
    const GpuTraceResult& g = traced.value();
    stats = CpuTraceStats{};
    stats.rays = g.rays;
    stats.hits = g.hits;
    stats.invalid_rays = g.invalid_rays;
    stats.stack_overflows = g.stack_overflows;
    stats.bad_indices = g.bad_indices;
    stats.nodes_visited = g.nodes_visited;
    stats.triangles_tested = g.triangles_tested;
    stats.seconds = g.kernel_ms * 1e-3;
    return true;
}

CpuTraceStats trace_cpu(const File& f, const std::vector<Ray>& rays, std::vector<Hit>& hits,
                        std::vector<uint32_t>& instances, const TraceRequest& r) {
    CpuTraceOptions o;
    o.mode = r.any ? HitMode::kAny : HitMode::kClosest;
    o.test = r.fast ? TriangleTest::kFast : TriangleTest::kWatertight;
    o.threads = r.threads;
    TwoLevelScene scene;
    if (two_level_scene(f, scene))
        return trace_two_level_cpu(scene, rays.data(), hits.data(), instances.data(), rays.size(), o);
    const auto tris = f.triangles();
    if (r.bvh2) {
        const auto n = f.bvh2();
        return trace_bvh2_cpu(n.data(), n.size(), tris.data(), tris.size(), rays.data(), hits.data(), rays.size(), o);
    }
    const auto n = f.nodes();
    return trace_cwbvh_cpu(n.data(), n.size(), tris.data(), tris.size(), rays.data(), hits.data(), rays.size(), o);
}

}  // namespace

int run_trace(int argc, char** argv) {
    const char* usage =
        "usage: cwbvh trace FILE --rays RAYS [--hits HITS] [--any] [--fast] [--bvh2] [--cpu|--gpu] "
        "[--threads N] [--repeat K] [--no-defer-hits] [--reference-node-test] [--postpone-percent P]";
    const char* path = nullptr;
    const char* rays_path = nullptr;
    const char* hits_path = nullptr;
    TraceRequest req;
    bool gpu = false, ab = false;
    uint32_t threads = 0, repeat = 1;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--rays") {
            if (!(rays_path = option_value(argc, argv, i))) return error(kExitUsage, "trace: --rays needs a path");
        } else if (a == "--hits") {
            if (!(hits_path = option_value(argc, argv, i))) return error(kExitUsage, "trace: --hits needs a path");
        } else if (a == "--any") {
            req.any = true;
        } else if (a == "--fast") {
            req.fast = true;
        } else if (a == "--bvh2") {
            req.bvh2 = true;
        } else if (a == "--cpu") {
            gpu = false;
        } else if (a == "--gpu") {
            gpu = true;
        } else if (a == "--threads") {
            if (!parse_u32(option_value(argc, argv, i), 0, 1024, threads))
                return error(kExitUsage, "trace: --threads needs an integer in [0, 1024]");
        } else if (a == "--repeat") {
            if (!parse_u32(option_value(argc, argv, i), 1, 1000, repeat))
                return error(kExitUsage, "trace: --repeat needs an integer in [1, 1000]");
        } else if (a == "--no-defer-hits") {
            req.ab.defer_hits = false;
            ab = true;
        } else if (a == "--reference-node-test") {
            req.ab.fast_node_test = false;
            ab = true;
        } else if (a == "--postpone-percent") {
            if (!parse_u32(option_value(argc, argv, i), 0, 100, req.ab.postpone_percent))
                return error(kExitUsage, "trace: --postpone-percent needs an integer in [0, 100]");
            ab = true;
        } else if (a.size() > 1 && a[0] == '-') {
            return error(kExitUsage, ("trace: unknown option " + a).c_str());
        } else if (path) {
            return error(kExitUsage, "trace: expects exactly one FILE");
        } else {
            path = argv[i];
        }
    }
    if (!path || !rays_path) return error(kExitUsage, usage);
    req.threads = threads;

    if (hits_path) {
        if (const Result r = check_output_path(hits_path, {path, rays_path}); !r.ok())
            return error(kExitBadInput, r.message.c_str());
    }
    auto file = File::open(path, {true, trace_section_mask(req.bvh2 ? kMaskBvh2 : 0u)});
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    const bool two_level = file->is_two_level();
    if (ab && (!gpu || req.bvh2 || two_level))
        return error(kExitUsage, "trace: --no-defer-hits, --reference-node-test and --postpone-percent change the "
                                 "CWBVH kernel of a single-level file: they need --gpu, without --bvh2");
    if (!req.ab.defer_hits && req.fast)
        return error(kExitUsage, "trace: --no-defer-hits with --fast: the fast triangle test never defers hits");
    if (two_level && req.bvh2)
        return error(kExitBadInput, (std::string(path) + ": a two-level scene: --bvh2 traces single-level files only "
                                                         "(compile with cwbvhc --flatten)")
                                        .c_str());
    if (req.bvh2 && file->bvh2().empty())
        return error(kExitBadInput, (std::string(path) + ": no BVH2 section (compile with --keep-sbvh)").c_str());
    std::vector<Ray> rays;
    std::string err;
    if (const Result r = read_ray_file(rays_path, rays); !r.ok()) return error(kExitBadInput, r.message.c_str());
    std::vector<Hit> hits(rays.size());
    std::vector<uint32_t> instances(two_level ? rays.size() : 0);

    std::vector<double> secs;
    CpuTraceStats s;
    for (uint32_t k = 0; k < repeat; ++k) {
        if (gpu) {
            if (!trace_gpu(*file, rays, hits, instances, req, s, err)) return error(kExitBadInput, err.c_str());
        } else {
            s = trace_cpu(*file, rays, hits, instances, req);
        }
        secs.push_back(s.seconds);
    }
    std::sort(secs.begin(), secs.end());
    const double median = secs[secs.size() / 2];
    const double n = double(std::max<uint64_t>(s.rays, 1));
    std::printf("backend          %s (%s, %s, %s)\n", gpu ? "gpu" : "cpu",
                req.bvh2 ? "bvh2" : (two_level ? "two-level cwbvh" : "cwbvh"),
                req.any ? "any-hit" : "closest-hit", req.fast ? "fast test" : "watertight test");
    std::printf("rays             %llu\n", (unsigned long long)s.rays);
    std::printf("hits             %llu (%.2f%%)\n", (unsigned long long)s.hits, 100.0 * double(s.hits) / n);
    std::printf("seconds          %.4f (median of %u)\n", median, repeat);
    std::printf("Mrays/s          %.3f\n", median > 0 ? double(s.rays) / median * 1e-6 : 0.0);
    std::printf("nodes/ray        %.2f\n", double(s.nodes_visited) / n);
    std::printf("triangles/ray    %.2f\n", double(s.triangles_tested) / n);
    if (s.invalid_rays)
        std::printf("invalid rays     %llu (answered with a miss)\n", (unsigned long long)s.invalid_rays);
    if (s.stack_overflows || s.bad_indices) {
        std::printf("stack overflows  %llu\nbad indices      %llu\n", (unsigned long long)s.stack_overflows,
                    (unsigned long long)s.bad_indices);
    }
    if (hits_path) {
        const uint32_t flags = (req.any ? kHitFileAnyHit : 0u) | (req.fast ? 0u : kHitFileWatertight);
        // Two-level: 20-byte records with the instance (hit file 1.1); else the 1.0 file.
        if (const Result r = write_hit_file(hits_path, hits.data(), two_level ? instances.data() : nullptr,
                                            hits.size(), flags);
            !r.ok())
            return error(kExitBadInput, r.message.c_str());
    }
    return (s.stack_overflows || s.bad_indices) ? kExitBadInput : kExitOk;
}

}  // namespace cwbvh::tool
