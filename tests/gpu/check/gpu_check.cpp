// cwbvh_gpu_check: the GPU correctness check and benchmark in one plain executable
// (no GoogleTest: the GPU machine has none). For each scene it generates rays in
// process (pinhole primary rays over the scene bounds, then diffuse bounces 1..4
// from the CPU reference hits, one ray per primary hit: see bounce_rays), traces them with the CPU reference
// (cwbvh_cpu_trace, watertight), the CWBVH kernel and the BVH2 kernel, compares,
// times, and prints a table last.
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
// Exit: 0 pass (or "SKIPPED: no CUDA device"), 1 mismatch, 2 usage/IO/CUDA error.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "cwbvh/cpu_trace.h"
#include "cwbvh/cuda_check.h"
#include "cwbvh/device_scene.h"
#include "cwbvh/gpu_trace.h"
#include "cwbvh/loader.h"
#include "cwbvh/synthetic.h"
#include "cwbvh/trace.h"

namespace {

using namespace cwbvh;

constexpr int kUlpBound = 4;

struct Scene {
    std::string name;
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRecord> tris;
    std::vector<Bvh2Node> bvh2;
    SceneBounds bounds{};
};

struct Row {
    std::string scene, rays_kind, kernel;
    size_t rays = 0;
    double mrays = 0, ratio = 0;
    double node_mib = 0, tri_mib = 0;
    uint64_t mismatches = 0, ties = 0, overflows = 0;
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

// ---- Ray generation -------------------------------------------------------

struct Rng {
    uint64_t s;
    float next() {
        s = s * 6364136223846793005ull + 1442695040888963407ull;
        return float(uint32_t(s >> 40)) * (1.0f / 16777216.0f);
    }
};

std::vector<Ray> primary_rays(const SceneBounds& b, int w, int h) {
    float c[3], ext[3];
    for (int a = 0; a < 3; ++a) {
        c[a] = 0.5f * (b.lo[a] + b.hi[a]);
        ext[a] = b.hi[a] - b.lo[a];
    }
    const float diag = std::sqrt(ext[0] * ext[0] + ext[1] * ext[1] + ext[2] * ext[2]);
    // Camera on the (1, 0.6, 1.4) diagonal looking at the centre, 50 degree vertical fov.
    float eye[3] = {c[0] + 0.55f * diag, c[1] + 0.35f * diag, c[2] + 0.8f * diag};
    float fwd[3] = {c[0] - eye[0], c[1] - eye[1], c[2] - eye[2]};
    auto norm = [](float* v) {
        const float l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int a = 0; a < 3; ++a) v[a] /= l;
    };
    norm(fwd);
    float right[3] = {fwd[2], 0.0f, -fwd[0]};  // fwd x up(0,1,0), negated for a right-handed image
    right[0] = -fwd[2];
    right[2] = fwd[0];
    norm(right);
    float up[3] = {right[1] * fwd[2] - right[2] * fwd[1], right[2] * fwd[0] - right[0] * fwd[2],
                   right[0] * fwd[1] - right[1] * fwd[0]};
    const float th = std::tan(0.5f * 50.0f * 3.14159265f / 180.0f), aspect = float(w) / float(h);
    std::vector<Ray> rays(size_t(w) * size_t(h));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float px = (2.0f * (x + 0.5f) / w - 1.0f) * th * aspect, py = (1.0f - 2.0f * (y + 0.5f) / h) * th;
            Ray& r = rays[size_t(y) * w + x];
            for (int a = 0; a < 3; ++a) {
                r.org[a] = eye[a];
                r.dir[a] = fwd[a] + px * right[a] + py * up[a];
            }
            r.tmin = 0.0f;
            r.tmax = kInfinity;
        }
    }
    return rays;
}

/// Cosine-weighted diffuse ray leaving the hit of `r` (false for a miss or a
/// degenerate triangle).
bool spawn(const Ray& r, const Hit& hit, const std::vector<const TriangleRecord*>& by_prim, float eps, Rng& rng,
           Ray& o) {
    if (hit.prim == kMissPrim || hit.prim >= by_prim.size() || !by_prim[hit.prim]) return false;
    const TriangleRecord& t = *by_prim[hit.prim];
    float p[3], e1[3], e2[3], n[3];
    for (int a = 0; a < 3; ++a) {
        p[a] = r.org[a] + hit.t * r.dir[a];
        e1[a] = t.v1[a] - t.v0[a];
        e2[a] = t.v2[a] - t.v0[a];
    }
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    const float l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(l > 0.0f) || !std::isfinite(l)) return false;
    for (float& v : n) v /= l;
    if (n[0] * r.dir[0] + n[1] * r.dir[1] + n[2] * r.dir[2] > 0.0f)
        for (float& v : n) v = -v;
    // Orthonormal basis (Duff et al. 2017).
    const float sign = std::copysign(1.0f, n[2]);
    const float aa = -1.0f / (sign + n[2]), bb = n[0] * n[1] * aa;
    const float tb[3] = {1.0f + sign * n[0] * n[0] * aa, sign * bb, -sign * n[0]};
    const float bt[3] = {bb, sign + n[1] * n[1] * aa, -n[1]};
    const float u1 = rng.next(), u2 = rng.next();
    const float rad = std::sqrt(u1), phi = 6.2831853f * u2;
    const float lx = rad * std::cos(phi), ly = rad * std::sin(phi), lz = std::sqrt(std::max(0.0f, 1.0f - u1));
    for (int a = 0; a < 3; ++a) {
        o.org[a] = p[a];
        o.dir[a] = lx * tb[a] + ly * bt[a] + lz * n[a];
    }
    o.tmin = eps;
    o.tmax = kInfinity;
    return true;
}

/// Diffuse bounce k: one ray per primary hit ("path"). A path whose previous
/// bounce hit continues from that hit; one that escaped restarts from its primary
/// hit with a fresh direction, so every bounce set has as many rays as the primary
/// set has hits (otherwise bounce 4 of an open scene is a handful of rays).
std::vector<Ray> bounce_rays(const std::vector<Ray>& prev, const std::vector<Hit>& prev_hits,
                             const std::vector<Ray>& anchors, const std::vector<Hit>& anchor_hits,
                             const std::vector<const TriangleRecord*>& by_prim, float eps, uint64_t seed) {
    std::vector<Ray> out(anchors.size());
    Rng rng{seed};
    for (size_t i = 0; i < anchors.size(); ++i) {
        const bool cont = i < prev.size() && spawn(prev[i], prev_hits[i], by_prim, eps, rng, out[i]);
        if (!cont && !spawn(anchors[i], anchor_hits[i], by_prim, eps, rng, out[i])) out[i] = anchors[i];
    }
    return out;
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

/// Median kernel time in ms over `repeat` runs; hits of the last run in `hits`.
double time_trace(const DeviceScene& ds, bool bvh2, const std::vector<Ray>& rays, std::vector<Hit>& hits,
                  bool any, int repeat, DeviceTraceStats& stats) {
    DevBuf<Ray> d_rays(rays.size());
    DevBuf<Hit> d_hits(rays.size());
    if (!rays.empty())
        CWBVH_CUDA_CHECK(cudaMemcpy(d_rays.p, rays.data(), rays.size() * sizeof(Ray), cudaMemcpyHostToDevice));
    cudaEvent_t a, b;
    CWBVH_CUDA_CHECK(cudaEventCreate(&a));
    CWBVH_CUDA_CHECK(cudaEventCreate(&b));
    std::vector<float> times;
    TraceOptions o;
    for (int i = 0; i < repeat + 1; ++i) {  // run 0: warm-up (module load, occupancy query)
        o.stats = i == repeat ? &stats : nullptr;
        CWBVH_CUDA_CHECK(cudaEventRecord(a));
        if (bvh2) trace_bvh2(ds, d_rays.p, d_hits.p, rays.size(), any ? Query::kAny : Query::kClosest, nullptr, o);
        else trace(ds, d_rays.p, d_hits.p, rays.size(), any ? Query::kAny : Query::kClosest, nullptr, o);
        CWBVH_CUDA_CHECK(cudaEventRecord(b));
        CWBVH_CUDA_CHECK(cudaEventSynchronize(b));
        float ms = 0;
        CWBVH_CUDA_CHECK(cudaEventElapsedTime(&ms, a, b));
        if (i > 0) times.push_back(ms);
    }
    CWBVH_CUDA_CHECK(cudaEventDestroy(a));
    CWBVH_CUDA_CHECK(cudaEventDestroy(b));
    hits.resize(rays.size());
    if (!rays.empty())
        CWBVH_CUDA_CHECK(cudaMemcpy(hits.data(), d_hits.p, rays.size() * sizeof(Hit), cudaMemcpyDeviceToHost));
    std::sort(times.begin(), times.end());
    return times[times.size() / 2];
}

int usage() {
    std::fprintf(stderr,
                 "usage: cwbvh_gpu_check [--width W] [--height H] [--repeat R] [--cpu-only] [SCENE.cwbvh...]\n"
                 "  no scene: a synthetic 20k-triangle scene. --cpu-only: generate rays and CPU reference only\n"
                 "  (exercises everything but the GPU; used where there is no device).\n");
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    int width = 1024, height = 768, repeat = 5;
    bool cpu_only = false;
    std::vector<std::string> paths;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto num = [&](int& v) {
            if (i + 1 >= argc) return false;
            v = std::atoi(argv[++i]);
            return v > 0;
        };
        if (a == "--width") { if (!num(width)) return usage(); }
        else if (a == "--height") { if (!num(height)) return usage(); }
        else if (a == "--repeat") { if (!num(repeat)) return usage(); }
        else if (a == "--cpu-only") cpu_only = true;
        else if (a == "-h" || a == "--help") return usage();
        else if (!a.empty() && a[0] == '-') return usage();
        else paths.push_back(a);
    }

    std::string why;
    const bool have_gpu = gpu_available(why);
    if (!have_gpu && !cpu_only) {
        std::printf("SKIPPED: no CUDA device (%s)\n", why.c_str());
        return 0;
    }

    std::vector<Scene> scenes;
    if (paths.empty()) {
        SyntheticOptions so;
        so.triangles = 20000;
        SceneData sd = make_synthetic_scene(so);
        scenes.push_back(Scene{"synthetic-20k", std::move(sd.nodes), std::move(sd.triangles), std::move(sd.bvh2),
                               sd.bounds});
    }
    for (const std::string& p : paths) {
        Expected<File> f = File::open(p);
        if (!f.ok()) {
            std::fprintf(stderr, "%s\n", f.error().message.c_str());
            return 2;
        }
        Scene s;
        s.name = p.substr(p.find_last_of('/') + 1);
        s.nodes.assign(f->nodes().begin(), f->nodes().end());
        s.tris.assign(f->triangles().begin(), f->triangles().end());
        s.bvh2.assign(f->bvh2().begin(), f->bvh2().end());
        if (f->bounds()) s.bounds = *f->bounds();
        scenes.push_back(std::move(s));
    }

    std::vector<Row> rows;
    bool failed = false;
    try {
        if (have_gpu) {
            cudaDeviceProp prop{};
            CWBVH_CUDA_CHECK(cudaGetDeviceProperties(&prop, 0));
            std::printf("device: %s (sm_%d%d, %d SMs)\n", prop.name, prop.major, prop.minor,
                        prop.multiProcessorCount);
            KernelInfo info[8];
            const int nk = kernel_info(info, 8);
            for (int k = 0; k < nk; ++k)
                std::printf("kernel %-26s regs %3d  local %5zu B  shared %6zu B  ptx %d  sass %d\n", info[k].name,
                            info[k].registers, info[k].local_bytes, info[k].shared_bytes, info[k].ptx_version,
                            info[k].binary_version);
        }
        for (const Scene& s : scenes) {
            std::vector<const TriangleRecord*> by_prim;
            for (const TriangleRecord& t : s.tris) {
                if (t.prim >= by_prim.size()) by_prim.resize(size_t(t.prim) + 1, nullptr);
                if (!by_prim[t.prim]) by_prim[t.prim] = &t;
            }
            float diag2 = 0;
            for (int a = 0; a < 3; ++a) diag2 += (s.bounds.hi[a] - s.bounds.lo[a]) * (s.bounds.hi[a] - s.bounds.lo[a]);
            const float eps = 1e-5f * std::sqrt(diag2);

            std::optional<DeviceScene> ds;
            double up_pinned = 0, up_pageable = 0;
            if (have_gpu) {
                UploadOptions uo;
                uo.method = UploadMethod::kPageable;
                {
                    auto tmp = DeviceScene::upload(s.nodes.data(), s.nodes.size(), s.tris.data(), s.tris.size(),
                                                   s.bvh2.data(), s.bvh2.size(), why, uo);
                    if (!tmp) throw std::runtime_error(why);
                    up_pageable = tmp->upload_stats().seconds * 1e3;
                }
                uo.method = UploadMethod::kPinnedStaging;
                ds = DeviceScene::upload(s.nodes.data(), s.nodes.size(), s.tris.data(), s.tris.size(), s.bvh2.data(),
                                         s.bvh2.size(), why, uo);
                if (!ds) throw std::runtime_error(why);
                up_pinned = ds->upload_stats().seconds * 1e3;
                std::printf("%s: upload %.1f MiB: pinned staging %.2f ms, pageable cudaMemcpy %.2f ms\n",
                            s.name.c_str(), double(ds->upload_stats().bytes) / 1048576.0, up_pinned, up_pageable);
            }

            std::vector<Ray> rays = primary_rays(s.bounds, width, height);
            std::vector<Ray> anchors;
            std::vector<Hit> anchor_hits;
            for (int bounce = 0; bounce <= 4; ++bounce) {
                std::vector<Hit> ref(rays.size()), ref_any(rays.size());
                CpuTraceOptions co;
                const CpuTraceStats cs = trace_cwbvh_cpu(s.nodes.data(), s.nodes.size(), s.tris.data(), s.tris.size(),
                                                         rays.data(), ref.data(), rays.size(), co);
                const std::string kind = bounce == 0 ? "primary" : "diffuse" + std::to_string(bounce);
                const bool report = bounce == 0 || bounce == 1 || bounce == 4;
                if (report) {
                    std::printf("%s %s: %zu rays, CPU %.2f Mrays/s, %llu hits\n", s.name.c_str(), kind.c_str(),
                                rays.size(), cs.seconds > 0 ? double(rays.size()) / cs.seconds / 1e6 : 0.0,
                                (unsigned long long)cs.hits);
                }
                if (have_gpu && report && !rays.empty()) {
                    co.mode = HitMode::kAny;
                    trace_cwbvh_cpu(s.nodes.data(), s.nodes.size(), s.tris.data(), s.tris.size(), rays.data(),
                                    ref_any.data(), rays.size(), co);
                    double cw_mrays = 0;
                    for (int k = 0; k < 2; ++k) {
                        const bool bvh2 = k == 1;
                        if (bvh2 && !ds->has_bvh2()) {
                            std::printf("  %s: no BVH2 section (compile with --keep-sbvh)\n", s.name.c_str());
                            continue;
                        }
                        for (int any = 0; any < 2; ++any) {
                            std::vector<Hit> hits;
                            DeviceTraceStats st;
                            const double ms = time_trace(*ds, bvh2, rays, hits, any != 0, repeat, st);
                            const Compare c = compare(hits, any ? ref_any : ref, any != 0);
                            Row r;
                            r.scene = s.name;
                            r.rays_kind = kind + (any ? "/any" : "");
                            r.kernel = bvh2 ? "bvh2" : "cwbvh";
                            r.rays = rays.size();
                            r.mrays = double(rays.size()) / (ms * 1e3);
                            if (!bvh2 && !any) cw_mrays = r.mrays;
                            if (bvh2 && !any && r.mrays > 0) r.ratio = cw_mrays / r.mrays;
                            r.node_mib = double(bvh2 ? ds->bvh2_bytes() : ds->node_bytes()) / 1048576.0;
                            r.tri_mib = double(ds->triangle_bytes()) / 1048576.0;
                            r.mismatches = c.mismatches;
                            r.ties = c.ties;
                            r.overflows = st.stack_overflows + st.bad_indices;
                            if (c.mismatches || st.bad_indices) {
                                failed = true;
                                const size_t i = size_t(c.first_bad);
                                if (c.first_bad >= 0)
                                    std::printf("  MISMATCH %s %s %s ray %zu: gpu prim %u t %.9g, cpu prim %u t %.9g\n",
                                                s.name.c_str(), r.rays_kind.c_str(), r.kernel.c_str(), i,
                                                hits[i].prim, double(hits[i].t), (any ? ref_any : ref)[i].prim,
                                                double((any ? ref_any : ref)[i].t));
                            }
                            rows.push_back(r);
                        }
                    }
                }
                if (bounce == 0) {
                    for (size_t i = 0; i < rays.size(); ++i) {
                        if (ref[i].prim == kMissPrim) continue;
                        anchors.push_back(rays[i]);
                        anchor_hits.push_back(ref[i]);
                    }
                    rays.clear();
                    ref.clear();
                }
                if (bounce < 4)
                    rays = bounce_rays(rays, ref, anchors, anchor_hits, by_prim, eps,
                                       0x9E3779B97F4A7C15ull * uint64_t(bounce + 1));
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cwbvh_gpu_check: %s\n", e.what());
        return 2;
    }

    if (!have_gpu) {
        std::printf("CPU-only run done (no CUDA device: %s)\n", why.c_str());
        return 0;
    }
    std::printf("\n%-22s %-14s %-6s %10s %9s %7s %9s %9s %8s %6s %6s\n", "scene", "rays", "kernel", "count",
                "Mrays/s", "cw/bvh2", "node MiB", "tri MiB", "mismatch", "ties", "ovfl");
    for (const Row& r : rows) {
        char ratio[16] = "";
        if (r.ratio > 0) std::snprintf(ratio, sizeof ratio, "%.2fx", r.ratio);
        std::printf("%-22s %-14s %-6s %10zu %9.1f %7s %9.2f %9.2f %8llu %6llu %6llu\n", r.scene.c_str(),
                    r.rays_kind.c_str(), r.kernel.c_str(), r.rays, r.mrays, ratio, r.node_mib, r.tri_mib,
                    (unsigned long long)r.mismatches, (unsigned long long)r.ties, (unsigned long long)r.overflows);
    }
    std::printf("%s\n", failed ? "RESULT: FAIL" : "RESULT: PASS");
    return failed ? 1 : 0;
}
