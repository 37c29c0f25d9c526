// cwbvh_bench_cpu FILE.cwbvh [--size N] [--repeats R] [--threads-max T] [--json OUT]
//                 [--camera ex,ey,ez,tx,ty,tz,fov]
//
// CPU throughput of the CWBVH reference traversal (cpu_trace.h, watertight test)
// next to Embree 3 single-ray queries (rtcIntersect1 / rtcOccluded1, scene built
// from the file's own triangles, build quality HIGH, default scene flags) on the
// same rays in the same run: primary camera rays (N x N, --camera or the default
// camera; bench/run.py passes the scene's first view of views/catalog.txt) and the
// diffuse bounce-1 rays spawned at their hits (the paper's two ray kinds), closest
// and any hit, 1..T threads (std::thread, interleaved blocks of 1024 rays for both).
// Each measurement alternates CWBVH and Embree R times and reports the medians and
// their ratio; on a shared, noisy machine the ratio is the figure to quote.
// Output: CSV on stdout, optional JSON.
#include <embree3/rtcore.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"

namespace {

using namespace cwbvh;

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

class EmbreeScene {
public:
    explicit EmbreeScene(std::span<const TriangleRecord> tris) {
        uint32_t max_prim = 0;
        for (const auto& t : tris) max_prim = std::max(max_prim, t.prim);
        std::vector<const TriangleRecord*> by_prim(tris.empty() ? 0 : size_t(max_prim) + 1, nullptr);
        for (const auto& t : tris)
            if (!by_prim[t.prim]) by_prim[t.prim] = &t;
        for (const auto* t : by_prim)
            if (t) prims_.push_back(t->prim), recs_.push_back(t);
        device_ = rtcNewDevice(nullptr);
        scene_ = rtcNewScene(device_);
        rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
        RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
        float* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), recs_.size() * 3));
        unsigned* idx = static_cast<unsigned*>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), recs_.size()));
        for (size_t i = 0; i < recs_.size(); ++i) {
            for (int a = 0; a < 3; ++a) {
                v[(i * 3 + 0) * 3 + a] = recs_[i]->v0[a];
                v[(i * 3 + 1) * 3 + a] = recs_[i]->v1[a];
                v[(i * 3 + 2) * 3 + a] = recs_[i]->v2[a];
            }
            for (int k = 0; k < 3; ++k) idx[i * 3 + k] = unsigned(i * 3 + k);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene_, g);
        rtcReleaseGeometry(g);
        rtcCommitScene(scene_);
    }
    ~EmbreeScene() {
        rtcReleaseScene(scene_);
        rtcReleaseDevice(device_);
    }
    /// Traces rays[b, e) one at a time; returns the hit count.
    uint64_t trace(const Ray* rays, Hit* hits, size_t b, size_t e, bool any) const {
        uint64_t n = 0;
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (size_t i = b; i < e; ++i) {
            const Ray& r = rays[i];
            RTCRayHit rh{};
            rh.ray.org_x = r.org[0], rh.ray.org_y = r.org[1], rh.ray.org_z = r.org[2];
            rh.ray.dir_x = r.dir[0], rh.ray.dir_y = r.dir[1], rh.ray.dir_z = r.dir[2];
            rh.ray.tnear = r.tmin, rh.ray.tfar = r.tmax, rh.ray.mask = 0xFFFFFFFFu;
            if (any) {
                rtcOccluded1(scene_, &ctx, &rh.ray);
                const bool h = rh.ray.tfar < 0.0f;
                hits[i] = h ? Hit{0, 0, 0, 0} : make_miss();
                n += h;
            } else {
                rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rtcIntersect1(scene_, &ctx, &rh);
                const bool h = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
                hits[i] = h ? Hit{rh.ray.tfar, rh.hit.u, rh.hit.v, prims_[rh.hit.primID]} : make_miss();
                n += h;
            }
        }
        return n;
    }

private:
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    std::vector<uint32_t> prims_;
    std::vector<const TriangleRecord*> recs_;
};

/// Embree over `threads` std::threads with the same interleaved 1024-ray blocks as cpu_trace.
double embree_seconds(const EmbreeScene& e, const std::vector<Ray>& rays, std::vector<Hit>& hits, bool any,
                      unsigned threads, uint64_t& hit_count) {
    constexpr size_t kBlock = 1024;
    std::atomic<uint64_t> total{0};
    const double t0 = now();
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < threads; ++t)
        pool.emplace_back([&, t] {
            uint64_t n = 0;
            for (size_t b = size_t(t) * kBlock; b < rays.size(); b += size_t(threads) * kBlock)
                n += e.trace(rays.data(), hits.data(), b, std::min(rays.size(), b + kBlock), any);
            total += n;
        });
    for (auto& th : pool) th.join();
    hit_count = total;
    return now() - t0;
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    const char* path = nullptr;
    const char* json_path = nullptr;
    const char* camera_text = nullptr;
    unsigned size = 512, repeats = 5, threads_max = 2;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto num = [&](unsigned& dst) {
            if (i + 1 >= argc) return false;
            dst = unsigned(std::strtoul(argv[++i], nullptr, 10));
            return dst > 0;
        };
        if (a == "--size") {
            if (!num(size)) return std::fprintf(stderr, "cwbvh_bench_cpu: error: --size N\n"), 2;
        } else if (a == "--repeats") {
            if (!num(repeats)) return std::fprintf(stderr, "cwbvh_bench_cpu: error: --repeats R\n"), 2;
        } else if (a == "--threads-max") {
            if (!num(threads_max)) return std::fprintf(stderr, "cwbvh_bench_cpu: error: --threads-max T\n"), 2;
        } else if (a == "--json" && i + 1 < argc) {
            json_path = argv[++i];
        } else if (a == "--camera" && i + 1 < argc) {
            camera_text = argv[++i];
        } else if (a[0] != '-' && !path) {
            path = argv[i];
        } else {
            std::fprintf(stderr,
                         "usage: cwbvh_bench_cpu FILE.cwbvh [--size N] [--repeats R] [--threads-max T] [--json OUT]\n");
            return 2;
        }
    }
    if (!path) {
        std::fprintf(stderr,
                     "usage: cwbvh_bench_cpu FILE.cwbvh [--size N] [--repeats R] [--threads-max T] [--json OUT]\n");
        return 2;
    }
    auto file = File::open(path);
    if (!file.ok()) return std::fprintf(stderr, "cwbvh_bench_cpu: error: %s\n", file.error().describe().c_str()), 1;
    const auto nodes = file->nodes();
    const auto tris = file->triangles();
    const EmbreeScene embree(tris);

    struct Set {
        const char* name;
        std::vector<Ray> rays;
    };
    std::vector<Set> sets;
    Camera camera = default_camera(*file->bounds());
    if (camera_text) {
        if (const Result r = parse_camera(camera_text, camera); !r.ok())
            return std::fprintf(stderr, "cwbvh_bench_cpu: error: %s\n", r.message.c_str()), 2;
    }
    sets.push_back({"primary", camera_rays(camera, size, size)});
    sets.push_back({"diffuse", diffuse_rays(nodes.data(), nodes.size(), tris.data(), tris.size(), sets[0].rays, 1, 1,
                                            threads_max).rays});

    std::string json = "{\"file\": \"" + std::string(path) + "\", \"triangles\": " + std::to_string(tris.size()) +
                       ", \"results\": [\n";
    std::printf("file,rays,count,query,threads,cwbvh_mrays,embree_mrays,ratio_cwbvh_over_embree,cwbvh_hits,embree_hits,"
                "nodes_per_ray,tris_per_ray\n");
    bool first = true;
    for (const Set& s : sets) {
        std::vector<Hit> hits(s.rays.size());
        for (bool any : {false, true})
            for (unsigned th = 1; th <= threads_max; ++th) {
                std::vector<double> tc, te;
                CpuTraceStats st;
                uint64_t eh = 0;
                CpuTraceOptions o;
                o.mode = any ? HitMode::kAny : HitMode::kClosest;
                o.threads = th;
                for (unsigned r = 0; r < repeats; ++r) {
                    st = trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), s.rays.data(),
                                         hits.data(), s.rays.size(), o);
                    tc.push_back(st.seconds);
                    te.push_back(embree_seconds(embree, s.rays, hits, any, th, eh));
                }
                const double n = double(s.rays.size());
                const double mc = n / median(tc) * 1e-6, me = n / median(te) * 1e-6;
                std::printf("%s,%s,%zu,%s,%u,%.3f,%.3f,%.3f,%llu,%llu,%.2f,%.2f\n", path, s.name, s.rays.size(),
                            any ? "any" : "closest", th, mc, me, mc / me, (unsigned long long)st.hits,
                            (unsigned long long)eh, double(st.nodes_visited) / n, double(st.triangles_tested) / n);
                std::fflush(stdout);
                char buf[512];
                std::snprintf(buf, sizeof buf,
                              "%s  {\"rays\": \"%s\", \"count\": %zu, \"query\": \"%s\", \"threads\": %u, "
                              "\"cwbvh_mrays\": %.3f, \"embree_mrays\": %.3f, \"ratio\": %.3f}",
                              first ? "" : ",\n", s.name, s.rays.size(), any ? "any" : "closest", th, mc, me, mc / me);
                json += buf;
                first = false;
            }
    }
    json += "\n]}\n";
    if (json_path) {
        FILE* f = std::fopen(json_path, "w");
        if (!f || std::fputs(json.c_str(), f) < 0 || std::fclose(f) != 0)
            return std::fprintf(stderr, "cwbvh_bench_cpu: error: %s: cannot write\n", json_path), 1;
    }
    return 0;
}
