// cwbvh_gpu_check: the GPU correctness check and benchmark in one plain executable
// (no GoogleTest: the GPU machine has none).
//
// Rays (the paper's benchmark, Ylitie et al. 2017 section 5, with the one ray
// generator of kernels/include/cwbvh/kernels/ray_gen.h): for every view of each scene in the
// view catalog (view_catalog.h: --views, else $CWBVH_VIEWS, else the compiled-in
// views/catalog.txt; the scene key is the file's stem; default_camera only for a
// scene not in the catalog), W x H primary rays (camera_rays), then diffuse bounces
// 1..4 (next_bounce, seed 1: the rays of `cwbvh rays --diffuse --bounce N --view V`
// at the same size). Paths END when they escape, so a bounce has as many rays as the
// previous bounce had hits.
//
// Each ray set is traced by the CPU reference (cwbvh_cpu_trace, watertight), the CWBVH
// kernel and the BVH2 kernel, closest and any hit. Timing: TraceOptions::kernel_ms
// (CUDA events around the kernel launches alone: no allocation, memset or copy),
// median of --repeat runs after one untimed warm-up; nodes/ray and triangles/ray come
// from one more run with DeviceTraceStats, outside the timed runs.
//
// Comparison (closest hit): a GPU hit matches the CPU hit when both miss, or both
// hit the same prim with |t_gpu - t_cpu| <= kUlpBound ulps. A different prim with t
// within the bound is counted as a "tie" (two triangles at the same distance: which
// one wins depends on test order, and postponing changes the order) and accepted.
// Anything else (hit vs miss, t out of bound) is a mismatch and fails the check.
// Why kUlpBound = 4: the watertight float path uses only correctly rounded
// operations (fp.h), so it is bit-identical on host and device; the double fallback
// may be contracted into FMAs by nvcc, which moves the double result by an ulp of
// double, and at most 1 float ulp after rounding; 4 leaves margin.
// Any hit: only hit/miss must agree.
//
// Output: one table row per scene, view, ray set and query with both kernels
// (Mrays/s, CWBVH/BVH2, nodes/ray and triangles/ray, mismatches), then the geometric
// means over scenes (a scene: the geometric mean over its views) of CWBVH/BVH2 and of
// CWBVH Mrays/s, closest hit, per ray set and for diffuse 1-4 together (per view: all
// diffuse rays over the summed kernel times), then "RESULT: PASS" or "RESULT: FAIL".
// --csv PATH writes the table (for bench/results/gpu/).
//
// Exit: 0 pass, or "SKIPPED: no CUDA device" when there is no device at all;
//       1 a mismatch or a corrupt-index report;
//       2 usage, I/O or CUDA error, a malformed view catalog, or a device that is
//         present but cannot run the kernels (driver too old, no kernel image, busy).
// --cpu-only runs everything but the GPU (ray generation and the CPU reference) and
// exits 0 (2 on errors).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"
#ifdef CWBVH_HAVE_SYNTHETIC  // builds with the compiler core (not in the GPU-only configuration)
#include "cwbvh/compiler/synthetic.h"
#endif
#include "cwbvh/kernels/trace.h"
#include "cwbvh/kernels/view_catalog.h"

namespace {

using namespace cwbvh;

constexpr int kUlpBound = 4;
constexpr int kBounces = 4;
constexpr uint32_t kSeed = 1;  // `cwbvh rays` default seed: the same diffuse rays

struct Scene {
    std::string name;  ///< scene key (file stem)
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRecord> tris;
    std::vector<Bvh2Node> bvh2;
    SceneBounds bounds{};
};

/// One kernel's result on one ray set and query.
struct KernelResult {
    bool ran = false;
    double ms = 0;  ///< median kernel time
    double mrays = 0;
    double nodes_per_ray = 0, tris_per_ray = 0;
    uint64_t mismatches = 0, ties = 0, overflows = 0, bad_indices = 0;
};

struct Row {
    std::string scene, view, rays_kind, query;
    int bounce = 0;  ///< 0 primary, 1..4 diffuse
    size_t rays = 0;
    uint64_t cpu_hits = 0;
    double cpu_mrays = 0;
    KernelResult k[2];  ///< [0] CWBVH, [1] BVH2
    double ratio() const { return k[0].ran && k[1].ran && k[1].mrays > 0 ? k[0].mrays / k[1].mrays : 0.0; }
};

uint32_t ulp_distance(float a, float b) {
    if (a == b) return 0;
    if (std::isinf(a) || std::isinf(b) || std::isnan(a) || std::isnan(b)) return 0xFFFFFFFFu;
    int32_t ia, ib;
    std::memcpy(&ia, &a, 4);
    std::memcpy(&ib, &b, 4);
    if (ia < 0) ia = int32_t(0x80000000u - uint32_t(ia));
    if (ib < 0) ib = int32_t(0x80000000u - uint32_t(ib));
    const int64_t d = int64_t(ia) - int64_t(ib);
    return uint32_t(std::min<int64_t>(d < 0 ? -d : d, 0xFFFFFFFF));
}

struct Compare {
    uint64_t mismatches = 0, ties = 0;
    int64_t first_bad = -1;
};

Compare compare(const std::vector<Hit>& gpu, const std::vector<Hit>& cpu, bool any) {
    Compare c;
    for (size_t i = 0; i < cpu.size(); ++i) {
        const bool gh = gpu[i].prim != kMissPrim, ch = cpu[i].prim != kMissPrim;
        bool bad = gh != ch;
        if (!bad && gh && !any) {
            const bool close = ulp_distance(gpu[i].t, cpu[i].t) <= uint32_t(kUlpBound);
            if (!close) bad = true;
            else if (gpu[i].prim != cpu[i].prim) ++c.ties;
        }
        if (bad) {
            if (c.first_bad < 0) c.first_bad = int64_t(i);
            ++c.mismatches;
        }
    }
    return c;
}

// ---- GPU helpers ---------------------------------------------------------

template <class T>
struct DevBuf {
    T* p = nullptr;
    explicit DevBuf(size_t n) {
        if (n) CWBVH_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&p), n * sizeof(T)));
    }
    ~DevBuf() {
        if (p) CWBVH_CUDA_WARN(cudaFree(p));
    }
    DevBuf(const DevBuf&) = delete;
    DevBuf& operator=(const DevBuf&) = delete;
};

/// Runs one kernel on `n` device rays: one untimed warm-up, `repeat` timed runs
/// (kernel launches alone), the hits of the last timed run into `hits`, then one
/// counting run for `stats`. Returns the median kernel time in ms.
double run_kernel(const DeviceScene& ds, bool bvh2, const Ray* d_rays, Hit* d_hits, size_t n, bool any, int repeat,
                  std::vector<Hit>& hits, DeviceTraceStats& stats) {
    const Query q = any ? Query::kAny : Query::kClosest;
    auto launch = [&](float* ms, DeviceTraceStats* st) {
        TraceOptions o;
        o.kernel_ms = ms;
        o.stats = st;
        if (bvh2) trace_bvh2(ds, d_rays, d_hits, n, q, nullptr, o);
        else trace(ds, d_rays, d_hits, n, q, nullptr, o);
    };
    launch(nullptr, nullptr);  // warm-up: lazy module load, occupancy query
    CWBVH_CUDA_CHECK(cudaDeviceSynchronize());
    std::vector<float> times;
    for (int i = 0; i < repeat; ++i) {
        float ms = 0;
        launch(&ms, nullptr);
        times.push_back(ms);
    }
    hits.resize(n);
    if (n) CWBVH_CUDA_CHECK(cudaMemcpy(hits.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost));
    launch(nullptr, &stats);
    std::sort(times.begin(), times.end());
    return times[times.size() / 2];
}

double geomean(const std::vector<double>& v) {
    if (v.empty()) return 0.0;
    double s = 0;
    for (double x : v) s += std::log(x);
    return std::exp(s / double(v.size()));
}

int usage() {
    std::fprintf(stderr,
                 "usage: cwbvh_gpu_check [--width W] [--height H] [--repeat R] [--views CATALOG] [--csv PATH]\n"
                 "                       [--cpu-only] [SCENE.cwbvh...]\n"
                 "  rays: every catalog view of each scene (default camera for a scene not in the catalog),\n"
                 "  W x H (default 2048 x 2048) primary rays and diffuse bounces 1-4; R timed runs (default 5).\n"
                 "  no scene: a synthetic 20k-triangle scene (builds with the compiler only). --cpu-only: generate "
                 "rays and CPU reference only\n"
                 "  (exercises everything but the GPU; used where there is no device).\n"
                 "  exit: 0 pass or SKIPPED (no CUDA device), 1 mismatch, 2 usage/IO/CUDA error or unusable device\n");
    return 2;
}

const char* kind_name(int bounce) {
    static const char* const k[] = {"primary", "diffuse1", "diffuse2", "diffuse3", "diffuse4"};
    return k[bounce];
}

void print_table(const std::vector<Row>& rows) {
    std::printf("\n%-18s %-10s %-9s %-7s %9s %7s | %8s %8s %7s | %6s %6s %6s %6s | %6s %6s %5s %5s\n", "scene",
                "view", "rays", "query", "count", "hit%", "CW Mr/s", "B2 Mr/s", "CW/B2", "CW n/r", "CW t/r", "B2 n/r",
                "B2 t/r", "CW mis", "B2 mis", "ties", "ovfl");
    for (const Row& r : rows) {
        char ratio[16] = "-", b2[16] = "-", b2n[16] = "-", b2t[16] = "-", b2m[24] = "-";
        if (r.k[1].ran) {
            std::snprintf(b2, sizeof b2, "%.1f", r.k[1].mrays);
            std::snprintf(b2n, sizeof b2n, "%.1f", r.k[1].nodes_per_ray);
            std::snprintf(b2t, sizeof b2t, "%.1f", r.k[1].tris_per_ray);
            std::snprintf(b2m, sizeof b2m, "%llu", (unsigned long long)r.k[1].mismatches);
        }
        if (r.ratio() > 0) std::snprintf(ratio, sizeof ratio, "%.2fx", r.ratio());
        std::printf(
            "%-18s %-10s %-9s %-7s %9zu %6.1f%% | %8.1f %8s %7s | %6.1f %6.1f %6s %6s | %6llu %6s %5llu %5llu\n",
            r.scene.c_str(), r.view.c_str(), r.rays_kind.c_str(), r.query.c_str(), r.rays,
            r.rays ? 100.0 * double(r.cpu_hits) / double(r.rays) : 0.0, r.k[0].mrays, b2, ratio, r.k[0].nodes_per_ray,
            r.k[0].tris_per_ray, b2n, b2t, (unsigned long long)r.k[0].mismatches, b2m,
            (unsigned long long)(r.k[0].ties + r.k[1].ties), (unsigned long long)(r.k[0].overflows + r.k[1].overflows));
    }
}

/// Geometric means over scenes (a scene = the geometric mean over its views), closest hit.
void print_summary(const std::vector<Row>& rows) {
    // key: scene -> view -> bounce -> row (closest hit only).
    std::map<std::string, std::map<std::string, std::map<int, const Row*>>> by;
    std::vector<std::string> scene_order;
    for (const Row& r : rows) {
        if (r.query != "closest") continue;
        if (!by.count(r.scene)) scene_order.push_back(r.scene);
        by[r.scene][r.view][r.bounce] = &r;
    }
    std::printf("\nGeometric mean over %zu scene(s) (each scene: geometric mean over its views), closest hit:\n",
                scene_order.size());
    std::printf("%-14s %8s %14s %10s %8s\n", "rays", "scenes", "CWBVH Mrays/s", "CWBVH/BVH2", "(scenes)");
    for (int set = 0; set <= kBounces + 1; ++set) {  // 0..4 per bounce, 5 = diffuse 1-4 together
        std::vector<double> mr, ratio;
        for (const std::string& s : scene_order) {
            std::vector<double> vmr, vratio;
            for (const auto& [view, bounces] : by[s]) {
                double cw_ms = 0, b2_ms = 0, n = 0;
                bool ok = true, have_b2 = true;
                for (int b = (set == kBounces + 1 ? 1 : set); b <= (set == kBounces + 1 ? kBounces : set); ++b) {
                    const auto it = bounces.find(b);
                    if (it == bounces.end() || !it->second->k[0].ran) {
                        ok = false;
                        break;
                    }
                    cw_ms += it->second->k[0].ms;
                    b2_ms += it->second->k[1].ms;
                    have_b2 = have_b2 && it->second->k[1].ran;
                    n += double(it->second->rays);
                }
                if (!ok || n == 0 || cw_ms <= 0) continue;
                vmr.push_back(n / (cw_ms * 1e3));
                if (have_b2 && b2_ms > 0) vratio.push_back(b2_ms / cw_ms);
            }
            if (!vmr.empty()) mr.push_back(geomean(vmr));
            if (!vratio.empty()) ratio.push_back(geomean(vratio));
        }
        const char* name = set <= kBounces ? kind_name(set) : "diffuse1-4";
        char rs[16] = "-";
        if (!ratio.empty()) std::snprintf(rs, sizeof rs, "%.2fx", geomean(ratio));
        std::printf("%-14s %8zu %14.1f %10s %8zu\n", name, mr.size(), geomean(mr), rs, ratio.size());
    }
}

bool write_csv(const std::string& path, const std::vector<Row>& rows, const std::string& device, int width,
               int height, int repeat) {
    std::ofstream f(path);
    if (!f) return false;
    f << "scene,view,rays,query,width,height,count,cpu_hits,device,repeat,cwbvh_ms,cwbvh_mrays,bvh2_ms,bvh2_mrays,"
         "cwbvh_over_bvh2,cwbvh_nodes_per_ray,cwbvh_tris_per_ray,bvh2_nodes_per_ray,bvh2_tris_per_ray,"
         "cwbvh_mismatches,bvh2_mismatches,cwbvh_ties,bvh2_ties,cwbvh_overflows,bvh2_overflows\n";
    auto num = [](bool ran, double v) {
        if (!ran) return std::string();
        char b[32];
        std::snprintf(b, sizeof b, "%.6g", v);
        return std::string(b);
    };
    auto cnt = [](bool ran, uint64_t v) { return ran ? std::to_string(v) : std::string(); };
    for (const Row& r : rows) {
        const KernelResult &c = r.k[0], &b = r.k[1];
        f << r.scene << ',' << r.view << ',' << r.rays_kind << ',' << r.query << ',' << width << ',' << height << ','
          << r.rays << ',' << r.cpu_hits << ",\"" << device << "\"," << repeat << ',' << num(c.ran, c.ms) << ','
          << num(c.ran, c.mrays) << ',' << num(b.ran, b.ms) << ',' << num(b.ran, b.mrays) << ','
          << num(r.ratio() > 0, r.ratio()) << ',' << num(c.ran, c.nodes_per_ray) << ',' << num(c.ran, c.tris_per_ray)
          << ',' << num(b.ran, b.nodes_per_ray) << ',' << num(b.ran, b.tris_per_ray) << ','
          << cnt(c.ran, c.mismatches) << ',' << cnt(b.ran, b.mismatches) << ',' << cnt(c.ran, c.ties) << ','
          << cnt(b.ran, b.ties) << ',' << cnt(c.ran, c.overflows) << ',' << cnt(b.ran, b.overflows) << '\n';
    }
    return bool(f);
}

}  // namespace

int main(int argc, char** argv) {
    int width = 2048, height = 2048, repeat = 5;
    bool cpu_only = false;
    std::string views_path, csv_path;
    std::vector<std::string> paths;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto num = [&](int& v, int hi) {
            if (i + 1 >= argc) return false;
            char* end = nullptr;
            const long x = std::strtol(argv[++i], &end, 10);
            if (*end != '\0' || x < 1 || x > hi) return false;
            v = int(x);
            return true;
        };
        auto str = [&](std::string& v) {
            if (i + 1 >= argc || !*argv[i + 1]) return false;
            v = argv[++i];
            return true;
        };
        if (a == "--width") { if (!num(width, 16384)) return usage(); }
        else if (a == "--height") { if (!num(height, 16384)) return usage(); }
        else if (a == "--repeat") { if (!num(repeat, 1000)) return usage(); }
        else if (a == "--views") { if (!str(views_path)) return usage(); }
        else if (a == "--csv") { if (!str(csv_path)) return usage(); }
        else if (a == "--cpu-only") cpu_only = true;
        else if (a == "-h" || a == "--help") return usage();
        else if (!a.empty() && a[0] == '-') return usage();
        else paths.push_back(a);
    }

    std::string why;
    const GpuStatus status = gpu_status(why);
    const bool have_gpu = status == GpuStatus::kReady && !cpu_only;
    if (!cpu_only) {
        if (status == GpuStatus::kNoDevice || status == GpuStatus::kNoCuda) {
            std::printf("SKIPPED: no CUDA device (%s)\n", why.c_str());
            return 0;
        }
        if (status != GpuStatus::kReady) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: a CUDA device is present but the kernels cannot run: %s\n",
                         why.c_str());
            return 2;
        }
    }

    // The view catalog. Only the compiled-in default may be missing (then every scene
    // gets the default camera); a named (--views, $CWBVH_VIEWS) or malformed one is an error.
    ViewCatalog catalog;
    {
        CatalogLoad loaded = CatalogLoad::kError;
        const Result load = load_view_catalog(views_path, catalog, loaded);
        const std::string& err = load.message;
        if (loaded == CatalogLoad::kError) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: %s\n", err.c_str());
            return 2;
        } else if (loaded == CatalogLoad::kAbsent) {
            std::printf("views: no catalog (%s): default cameras\n", err.c_str());
        } else {
            std::printf("views: %s (%zu views)\n", catalog.source().c_str(), catalog.views().size());
        }
    }

    std::vector<Scene> scenes;
    if (paths.empty()) {
#ifdef CWBVH_HAVE_SYNTHETIC
        SyntheticOptions so;
        so.triangles = 20000;
        SceneData sd = make_synthetic_scene(so);
        scenes.push_back(Scene{"synthetic-20k", std::move(sd.nodes), std::move(sd.triangles), std::move(sd.bvh2),
                               sd.bounds});
#else
        std::fprintf(stderr, "cwbvh_gpu_check: error: no scene given (this build has no compiler core, so no "
                             "synthetic scene: pass SCENE.cwbvh files)\n");
        return 2;
#endif
    }
    for (const std::string& p : paths) {
        Expected<File> f = File::open(p);
        if (!f.ok()) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: %s\n", f.error().describe().c_str());
            return 2;
        }
        Scene s;
        s.name = scene_key(p);
        s.nodes.assign(f->nodes().begin(), f->nodes().end());
        s.tris.assign(f->triangles().begin(), f->triangles().end());
        s.bvh2.assign(f->bvh2().begin(), f->bvh2().end());
        if (f->bounds()) s.bounds = *f->bounds();
        scenes.push_back(std::move(s));
    }

    std::vector<Row> rows;
    std::string device_name = "cpu-only";
    bool failed = false;
    try {
        if (have_gpu) {
            cudaDeviceProp prop{};
            CWBVH_CUDA_CHECK(cudaGetDeviceProperties(&prop, 0));
            device_name = prop.name;
            std::printf("device: %s (sm_%d%d, %d SMs)\n", prop.name, prop.major, prop.minor,
                        prop.multiProcessorCount);
            KernelInfo info[8];
            const int nk = kernel_info(info, 8);
            for (int k = 0; k < nk; ++k)
                std::printf("kernel %-26s regs %3d  local %5zu B  shared %6zu B  ptx %d  sass %d\n", info[k].name,
                            info[k].registers, info[k].local_bytes, info[k].shared_bytes, info[k].ptx_version,
                            info[k].binary_version);
        }
        std::printf("rays: %dx%d per view, diffuse bounces 1-%d (paths end when they escape), seed %u, "
                    "%d timed runs\n", width, height, kBounces, kSeed, repeat);
        for (const Scene& s : scenes) {
            const PrimTable table(s.tris.data(), s.tris.size());
            std::optional<DeviceScene> ds;
            if (have_gpu) {
                UploadOptions uo;
                uo.method = UploadMethod::kPageable;
                double up_pageable = 0;
                {
                    auto tmp = DeviceScene::upload(s.nodes.data(), s.nodes.size(), s.tris.data(), s.tris.size(),
                                                   s.bvh2.data(), s.bvh2.size(), uo);
                    if (!tmp.ok()) throw std::runtime_error(tmp.error().message);
                    up_pageable = tmp->upload_stats().seconds * 1e3;
                }
                uo.method = UploadMethod::kPinnedStaging;
                auto up = DeviceScene::upload(s.nodes.data(), s.nodes.size(), s.tris.data(), s.tris.size(),
                                              s.bvh2.data(), s.bvh2.size(), uo);
                if (!up.ok()) throw std::runtime_error(up.error().message);
                ds = std::move(up.value());
                std::printf("%s: upload %.1f MiB: pinned staging %.2f ms, pageable cudaMemcpy %.2f ms\n",
                            s.name.c_str(), double(ds->upload_stats().bytes) / 1048576.0,
                            ds->upload_stats().seconds * 1e3, up_pageable);
                if (!ds->has_bvh2())
                    std::printf("%s: no BVH2 section (compile with --keep-sbvh): CWBVH kernel only\n", s.name.c_str());
            }

            for (const View& view : benchmark_views(catalog, s.name, s.bounds)) {
                std::printf("%s view %s: %s%s\n", s.name.c_str(), view.name.c_str(),
                            format_camera(view.camera).c_str(), view.line ? "" : " (not in the catalog)");
                DiffuseRays cur;
                cur.rays = camera_rays(view.camera, uint32_t(width), uint32_t(height));
                cur.path.resize(cur.rays.size());
                for (size_t i = 0; i < cur.path.size(); ++i) cur.path[i] = uint32_t(i);
                for (int bounce = 0; bounce <= kBounces; ++bounce) {
                    const std::vector<Ray>& rays = cur.rays;
                    std::vector<Hit> ref(rays.size()), ref_any(rays.size());
                    CpuTraceOptions co;
                    const CpuTraceStats cs = trace_cwbvh_cpu(s.nodes.data(), s.nodes.size(), s.tris.data(),
                                                             s.tris.size(), rays.data(), ref.data(), rays.size(), co);
                    co.mode = HitMode::kAny;
                    const CpuTraceStats ca = trace_cwbvh_cpu(s.nodes.data(), s.nodes.size(), s.tris.data(),
                                                             s.tris.size(), rays.data(), ref_any.data(), rays.size(),
                                                             co);
                    const double cpu_mrays = cs.seconds > 0 ? double(rays.size()) / cs.seconds / 1e6 : 0.0;
                    std::printf("  %-9s %9zu rays, %9llu hits (%5.1f%%), any-hit %9llu, CPU %.2f Mrays/s\n",
                                kind_name(bounce), rays.size(), (unsigned long long)cs.hits,
                                rays.empty() ? 0.0 : 100.0 * double(cs.hits) / double(rays.size()),
                                (unsigned long long)ca.hits, cpu_mrays);
                    if (ca.hits != cs.hits) {
                        std::printf("  MISMATCH %s %s %s: CPU closest hit %llu rays, any hit %llu\n", s.name.c_str(),
                                    view.name.c_str(), kind_name(bounce), (unsigned long long)cs.hits,
                                    (unsigned long long)ca.hits);
                        failed = true;
                    }
                    for (int any = 0; any < 2; ++any) {
                        Row r;
                        r.scene = s.name;
                        r.view = view.name;
                        r.rays_kind = kind_name(bounce);
                        r.bounce = bounce;
                        r.query = any ? "any" : "closest";
                        r.rays = rays.size();
                        r.cpu_hits = any ? ca.hits : cs.hits;
                        r.cpu_mrays = any ? (ca.seconds > 0 ? double(rays.size()) / ca.seconds / 1e6 : 0.0)
                                          : cpu_mrays;
                        rows.push_back(r);
                    }
                    if (have_gpu && !rays.empty()) {
                        DevBuf<Ray> d_rays(rays.size());
                        DevBuf<Hit> d_hits(rays.size());
                        CWBVH_CUDA_CHECK(cudaMemcpy(d_rays.p, rays.data(), rays.size() * sizeof(Ray),
                                                    cudaMemcpyHostToDevice));
                        for (int any = 0; any < 2; ++any) {
                            Row& r = rows[rows.size() - 2 + size_t(any)];
                            for (int k = 0; k < 2; ++k) {
                                const bool bvh2 = k == 1;
                                if (bvh2 && !ds->has_bvh2()) continue;
                                std::vector<Hit> hits;
                                DeviceTraceStats st;
                                const double ms = run_kernel(*ds, bvh2, d_rays.p, d_hits.p, rays.size(), any != 0,
                                                             repeat, hits, st);
                                const std::vector<Hit>& cpu = any ? ref_any : ref;
                                const Compare c = compare(hits, cpu, any != 0);
                                KernelResult& kr = r.k[k];
                                kr.ran = true;
                                kr.ms = ms;
                                kr.mrays = ms > 0 ? double(rays.size()) / (ms * 1e3) : 0.0;
                                kr.nodes_per_ray = double(st.nodes_visited) / double(rays.size());
                                kr.tris_per_ray = double(st.triangles_tested) / double(rays.size());
                                kr.mismatches = c.mismatches;
                                kr.ties = c.ties;
                                kr.overflows = st.stack_overflows;
                                kr.bad_indices = st.bad_indices;
                                if (c.mismatches || st.bad_indices) {
                                    failed = true;
                                    if (st.bad_indices)
                                        std::printf("  BAD INDICES %s %s %s %s %s: %llu\n", s.name.c_str(),
                                                    view.name.c_str(), r.rays_kind.c_str(), r.query.c_str(),
                                                    bvh2 ? "bvh2" : "cwbvh", (unsigned long long)st.bad_indices);
                                    if (c.first_bad >= 0) {
                                        const size_t i = size_t(c.first_bad);
                                        std::printf("  MISMATCH %s %s %s %s %s ray %zu: gpu prim %u t %.9g, cpu prim "
                                                    "%u t %.9g (%llu mismatches)\n",
                                                    s.name.c_str(), view.name.c_str(), r.rays_kind.c_str(),
                                                    r.query.c_str(), bvh2 ? "bvh2" : "cwbvh", i, hits[i].prim,
                                                    double(hits[i].t), cpu[i].prim, double(cpu[i].t),
                                                    (unsigned long long)c.mismatches);
                                    }
                                }
                            }
                        }
                    }
                    if (bounce < kBounces) cur = next_bounce(table, cur, ref, kSeed, uint32_t(bounce + 1));
                }
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cwbvh_gpu_check: error: %s\n", e.what());
        return 2;
    }

    if (!csv_path.empty() && !write_csv(csv_path, rows, device_name, width, height, repeat)) {
        std::fprintf(stderr, "cwbvh_gpu_check: error: %s: cannot write the CSV\n", csv_path.c_str());
        return 2;
    }
    if (!have_gpu) {
        std::printf("CPU-only run done (%s)%s\n", why.empty() ? "--cpu-only" : why.c_str(),
                    failed ? ": CPU closest/any-hit disagreement" : "");
        return failed ? 1 : 0;
    }
    print_table(rows);
    print_summary(rows);
    std::printf("%s\n", failed ? "RESULT: FAIL" : "RESULT: PASS");
    return failed ? 1 : 0;
}
