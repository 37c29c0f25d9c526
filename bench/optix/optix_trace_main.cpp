// cwbvh_optix_trace FILE.cwbvh --rays RAYS [--any] [--hits OUT] [--ref HITS] [--repeat R]
// The OptiX peer on one ray file (spec/rays.md; `cwbvh rays` writes them), the
// counterpart of `cwbvh trace FILE --rays RAYS --gpu`: builds the GAS from the file's
// stored triangles (TRIS section, through the loader), traces the rays (median of R
// timed launches after one warm-up, events around optixLaunch alone), prints Mrays/s
// and the GAS figures, writes the hits (OUT) and, with --ref (e.g. the hits of
// `cwbvh trace --hits`), compares them by tools/gpu_check/hit_compare.h within
// kOptixUlpBound: mismatches beyond equal-t ties are counted.
// Exit: 0 done (mismatches are printed, not a failure), 1 bad input, 2 usage,
// 3 no CUDA device or OptiX cannot run here (one line says why).
#include <cuda_runtime_api.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/loader/loader.h"
#include "hit_compare.h"
#include "optix_peer.h"

namespace {

int usage() {
    std::fprintf(stderr,
                 "usage: cwbvh_optix_trace FILE.cwbvh --rays RAYS [--any] [--hits OUT] [--ref HITS] [--repeat R]\n");
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    using namespace cwbvh;
    std::string scene, rays_path, hits_path, ref_path;
    bool any = false;
    int repeat = 5;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const bool has_value = i + 1 < argc;
        if (a == "--rays" && has_value) rays_path = argv[++i];
        else if (a == "--hits" && has_value) hits_path = argv[++i];
        else if (a == "--ref" && has_value) ref_path = argv[++i];
        else if (a == "--repeat" && has_value) repeat = std::max(1, std::atoi(argv[++i]));
        else if (a == "--any") any = true;
        else if (!a.empty() && a[0] != '-' && scene.empty()) scene = a;
        else return usage();
    }
    if (scene.empty() || rays_path.empty()) return usage();
    if (!hits_path.empty()) {  // never overwrite an input (the tools' one check)
        std::vector<std::string> inputs{scene, rays_path};
        if (!ref_path.empty()) inputs.push_back(ref_path);
        if (const Result r = check_output_path(hits_path, inputs); !r.ok()) {
            std::fprintf(stderr, "cwbvh_optix_trace: error: %s\n", r.message.c_str());
            return 2;
        }
    }

    Expected<File> file = File::open(scene);
    if (!file.ok()) {
        std::fprintf(stderr, "cwbvh_optix_trace: error: %s\n", file.error().describe().c_str());
        return 1;
    }
    std::vector<Ray> rays;
    if (const Result r = read_ray_file(rays_path, rays); !r.ok()) {
        std::fprintf(stderr, "cwbvh_optix_trace: error: %s\n", r.message.c_str());
        return 1;
    }
    std::vector<Hit> ref;
    uint32_t ref_flags = 0;
    if (!ref_path.empty()) {
        if (const Result r = read_hit_file(ref_path, ref, ref_flags); !r.ok()) {
            std::fprintf(stderr, "cwbvh_optix_trace: error: %s\n", r.message.c_str());
            return 1;
        }
        if (ref.size() != rays.size() || bool(ref_flags & kHitFileAnyHit) != any) {
            std::fprintf(stderr, "cwbvh_optix_trace: error: %s: %zu %s hits for %zu rays (%s query)\n",
                         ref_path.c_str(), ref.size(), (ref_flags & kHitFileAnyHit) ? "any" : "closest",
                         rays.size(), any ? "any" : "closest");
            return 1;
        }
    }
    int devices = 0;
    if (cudaGetDeviceCount(&devices) != cudaSuccess || devices == 0) {
        std::printf("SKIPPED: no CUDA device\n");
        return 3;
    }
    std::string why;
    std::unique_ptr<OptixPeer> peer = OptixPeer::create(why);
    if (!peer) {
        std::printf("SKIPPED: OptiX: %s\n", why.c_str());
        return 3;
    }
    try {
        const auto tris = file->triangles();
        const OptixGasInfo g = peer->build(tris.data(), tris.size());
        std::printf("%s: %s, GAS %llu triangles: build %.1f ms, compact %.1f ms, %.1f MiB (%.1f B/triangle)\n",
                    scene.c_str(), OptixPeer::version().c_str(), (unsigned long long)g.triangles, g.build_ms,
                    g.compact_ms, double(g.gas_bytes) / 1048576.0,
                    double(g.gas_bytes) / double(std::max<uint64_t>(g.triangles, 1)));
        Ray* d_rays = nullptr;
        Hit* d_hits = nullptr;
        const size_t n = rays.size();
        CWBVH_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&d_rays), std::max<size_t>(n, 1) * sizeof(Ray)));
        CWBVH_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&d_hits), std::max<size_t>(n, 1) * sizeof(Hit)));
        CWBVH_CUDA_CHECK(cudaMemcpy(d_rays, rays.data(), n * sizeof(Ray), cudaMemcpyHostToDevice));
        peer->trace(d_rays, d_hits, n, any);  // warm-up
        std::vector<float> times;
        for (int i = 0; i < repeat; ++i) {
            float ms = 0;
            peer->trace(d_rays, d_hits, n, any, &ms);
            times.push_back(ms);
        }
        std::sort(times.begin(), times.end());
        std::vector<Hit> hits(n);
        CWBVH_CUDA_CHECK(cudaMemcpy(hits.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost));
        CWBVH_CUDA_WARN(cudaFree(d_rays));
        CWBVH_CUDA_WARN(cudaFree(d_hits));
        const double ms = times[times.size() / 2];
        const size_t nhit = size_t(std::count_if(hits.begin(), hits.end(), [](const Hit& h) {
            return h.prim != kMissPrim;
        }));
        std::printf("%zu rays (%s), %zu hits, %.3f ms, %.1f Mrays/s (median of %d launches)\n", n,
                    any ? "any hit" : "closest hit", nhit, ms, ms > 0 ? double(n) / (ms * 1e3) : 0.0, repeat);
        if (!ref.empty()) {
            const HitCompare c = compare_hits(hits, ref, any, kOptixUlpBound);
            std::printf("against %s: %llu mismatches (%llu hit vs miss), %llu equal-t ties (t within %u ulps)\n",
                        ref_path.c_str(), (unsigned long long)c.mismatches, (unsigned long long)c.hit_vs_miss,
                        (unsigned long long)c.ties, kOptixUlpBound);
        }
        if (!hits_path.empty()) {
            if (const Result r = write_hit_file(hits_path, hits.data(), n, any ? kHitFileAnyHit : 0u); !r.ok()) {
                std::fprintf(stderr, "cwbvh_optix_trace: error: %s\n", r.message.c_str());
                return 1;
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cwbvh_optix_trace: error: %s\n", e.what());
        return 2;
    }
    return 0;
}
