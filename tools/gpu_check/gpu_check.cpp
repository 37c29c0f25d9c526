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
// kernel, the BVH2 kernel and, in a build with the OptiX headers (bench/optix), the
// OptiX 9.0 peer over a GAS of the same triangles, closest and any hit. Timing:
// TraceOptions::kernel_ms for our kernels, OptixPeer::trace's launch_ms for OptiX (CUDA
// events around the launches alone: no allocation, memset or copy), median of --repeat
// runs after one untimed warm-up; nodes/ray and triangles/ray come from one more run
// with DeviceTraceStats, outside the timed runs (OptiX reports none).
//
// Comparison: hit_compare.h (one function for all three). Our kernels must match the
// CPU reference within kKernelUlpBound (a different prim at the same t is a tie,
// accepted); any mismatch fails the check. OptiX's own triangle test is compared
// within kOptixUlpBound, and its disagreements beyond equal-t ties are counted and
// printed ("OX mis", of which hit-vs-miss in the CSV), never a failure.
//
// Output: one table row per scene, view, ray set and query with the kernels side by
// side (Mrays/s, CWBVH/BVH2, CWBVH/OptiX, nodes/ray and triangles/ray, mismatches), a
// per-scene table (triangles, .cwbvh size and compile time from --compile-times, the
// CWBVH device bytes per triangle beside OptiX's compacted GAS bytes per triangle and
// build time), then the geometric means over scenes (a scene: the geometric mean over
// its views) of CWBVH/BVH2, CWBVH/OptiX and Mrays/s, closest hit, per ray set and for
// diffuse 1-4 together (per view: all diffuse rays over the summed kernel times), then
// "RESULT: PASS" or "RESULT: FAIL". A ray set of fewer than kMinRaysForMeans (1M) rays
// (an open scene's later bounces, or a small --width/--height) is printed, marked '*',
// and kept out of the geometric means; for diffuse 1-4 together the view's summed ray
// count decides. The means say how many sets they left out.
// The inline query (cwbvh/kernels/query.h: intersect, one thread per ray, as a renderer's
// own kernel calls it; inline_kernel.cu) traces every ray set of a single-level file too,
// closest and any hit, timed as the kernels are; its hits must be the CPU reference's
// (compare_query, below: the same traversal code, but with the fast node test, which may
// visit extra leaves: equal-t ties and another valid any hit are accepted; a mismatch fails
// the check). Its speed beside the
// CWBVH kernel's: the "inline query" means after the others, and the CSV's inline_* columns.
// --csv PATH writes the table (for bench/results/gpu/), after every scene as well, so that a run
// cut short (a time limit, a CUDA error) keeps the scenes it finished.
//
// Two-level scenes (issue 19; format 1.2: MESH, INST, TLAS): a two-level file is given
// beside the flattened file of the same scene key (the same stem, another folder:
// scripts/gpu-check.sh passes SCENES/NAME.cwbvh and SCENES/instanced/NAME.cwbvh), in any
// order; a two-level file without its flattened partner is a usage error (its rays come
// from the flattened file). The SAME world rays (the flattened file's catalog views; the
// diffuse bounces from the flattened file's CPU reference hits) are then also traced by
// trace_two_level_cpu (closest and any) and the two-level kernel (trace_two_level, timed
// like the others: events around the launches, median of --repeat after a warm-up). The
// kernel must give the CPU reference's hits (hit_compare.h, compare_query: closest hit bit
// for bit, Hit record and instance, up to equal-t ties and the double path's ulps; any hit:
// hit/miss, and no hit nearer than the closest; a mismatch fails the check, "2L mis"; the
// inline query is held to the same). Its hits are compared with the flattened file's CWBVH
// kernel hits (on the CPU with --cpu-only: the two CPU references) by
// hit_compare.h's compare_with_flattened: hit/miss equal, t within 1e-5 relative, the
// same PMAP source or an equal-t tie; disagreements are counted and printed per view,
// ray set and query (edge cases and diffuse rounding apart), never a failure. Extra
// output: one line per ray set and query, the two-level table (Mrays/s of the two-level
// kernel beside the flattened file's CWBVH kernel, ratio, nodes and triangles per ray,
// the comparisons), the instanced file's size and compile time beside the flattened ones
// in the scene table (--compile-times key "instanced:NAME"), and the geometric means of
// two-level / flattened CWBVH Mrays/s per ray set (target >= 0.8, issue 19). With --csv,
// PATH's stem + "_two_level.csv" holds the two-level rows.
//
// Exit: 0 pass, or "SKIPPED: no CUDA device" when there is no device at all;
//       1 a mismatch or a corrupt-index report;
//       2 usage, I/O or CUDA error, a malformed view catalog, or a device that is
//         present but cannot run the kernels (driver too old, no kernel image, busy).
// --cpu-only runs everything but the GPU (ray generation and the CPU reference) and
// exits 0 (2 on errors).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "cwbvh/format/file_io.h"
#include "cwbvh/format/source_map.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/kernels/fast_node_selfcheck.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"
#ifdef CWBVH_HAVE_SYNTHETIC  // builds with the compiler core (not in the GPU-only configuration)
#include "cwbvh/compiler/synthetic.h"
#endif
#include "cwbvh/kernels/trace.h"
#include "cwbvh/kernels/view_catalog.h"
#include "hit_compare.h"
#include "inline_kernel.h"
#include "summary.h"
#ifdef CWBVH_HAVE_OPTIX  // bench/optix, built when the OptiX headers are given
#include "optix_peer.h"
#endif

namespace {

using namespace cwbvh;

using namespace cwbvh::gpu_check;  // summary.h: the rows, their means and the summary tables

constexpr uint32_t kSeed = 1;  // `cwbvh rays` default seed: the same diffuse rays

/// The two-level (instanced) file of a scene, beside its flattened file.
struct Instanced {
    std::string path;
    std::vector<CwbvhNode> top, nodes;  ///< TLAS; NODE (the bottom levels)
    std::vector<TriangleRecord> tris;
    std::vector<InstanceRecord> inst;
    std::vector<MeshRecord> meshes;
    std::vector<SourceRange> pmap;
    uint64_t triangles = 0;            ///< distinct stored triangles
    uint64_t instanced_triangles = 0;  ///< placed (the flattened scene's)
    uint64_t file_bytes = 0;
    double compile_s = -1;  ///< --compile-times "instanced:NAME", -1 unknown
    TwoLevelScene view() const {
        return TwoLevelScene{top.data(),    uint32_t(top.size()),   inst.data(), uint32_t(inst.size()),
                             meshes.data(), uint32_t(meshes.size()), nodes.data(), uint32_t(nodes.size()),
                             tris.data(),   uint32_t(tris.size())};
    }
    TwoLevelSections sections() const {
        TwoLevelSections t;
        t.top_nodes = top.data();
        t.top_node_count = top.size();
        t.instances = inst.data();
        t.instance_count = inst.size();
        t.meshes = meshes.data();
        t.mesh_count = meshes.size();
        return t;
    }
};

struct Scene {
    std::string name;  ///< scene key (file stem)
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRecord> tris;
    std::vector<Bvh2Node> bvh2;
    SceneBounds bounds{};
    uint64_t triangles = 0;   ///< stored triangles
    uint64_t file_bytes = 0;  ///< the .cwbvh file
    double compile_s = -1;    ///< cwbvhc wall time (--compile-times), -1 unknown
    bool gas = false;         ///< OptiX GAS built (the fields below are set)
    uint64_t gas_bytes = 0;
    double gas_build_ms = 0, gas_compact_ms = 0;
    std::vector<SourceRange> pmap;   ///< the flattened file's PMAP (two-level comparison)
    std::optional<Instanced> two;    ///< the instanced file of the same scene key, if given
};

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

/// kCwbvhNoDefer, kCwbvhRefNode: the CWBVH kernel with TraceOptions::defer_hits = false, or
/// with fast_node_test = false.
enum class Kernel { kCwbvh, kBvh2, kTwoLevel, kCwbvhNoDefer, kCwbvhRefNode };

/// Runs one kernel on `n` device rays: one untimed warm-up, `repeat` timed runs
/// (kernel launches alone), the hits of the last timed run into `hits` (and, for the
/// two-level kernel, its instances from d_inst into *inst), then one counting run for
/// `stats`. Returns the median kernel time in ms.
double run_kernel(const DeviceScene& ds, Kernel kernel, const Ray* d_rays, Hit* d_hits, size_t n, bool any, int repeat,
                  std::vector<Hit>& hits, DeviceTraceStats& stats, uint32_t* d_inst = nullptr,
                  std::vector<uint32_t>* inst = nullptr, uint32_t postpone_percent = kDefaultPostponePercent) {
    const Query q = any ? Query::kAny : Query::kClosest;
    auto launch = [&](float* ms, DeviceTraceStats* st) {
        TraceOptions o;
        o.kernel_ms = ms;
        o.stats = st;
        o.defer_hits = kernel != Kernel::kCwbvhNoDefer;
        o.fast_node_test = kernel != Kernel::kCwbvhRefNode;
        o.postpone_percent = postpone_percent;
        if (kernel == Kernel::kBvh2) trace_bvh2(ds, d_rays, d_hits, n, q, nullptr, o);
        else if (kernel == Kernel::kTwoLevel) trace_two_level(ds, d_rays, d_hits, d_inst, n, q, nullptr, o);
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
    if (inst) {
        inst->resize(n);
        if (n) CWBVH_CUDA_CHECK(cudaMemcpy(inst->data(), d_inst, n * sizeof(uint32_t), cudaMemcpyDeviceToHost));
    }
    launch(nullptr, &stats);
    std::sort(times.begin(), times.end());
    return times[times.size() / 2];
}

/// The inline query (inline_kernel.h) timed as run_kernel times the kernels: one untimed
/// warm-up, `repeat` timed launches, the hits of the last one; not_ok: the rays of the
/// last launch whose status is kStackOverflow, kBadIndex or kWrongScene. inst (set for a
/// two-level view): the hits' instances.
double run_inline(const SceneView& view, const Ray* d_rays, Hit* d_hits, size_t n, bool any, int repeat,
                  std::vector<Hit>& hits, uint64_t& not_ok, std::vector<uint32_t>* inst = nullptr) {
    DevBuf<unsigned long long> d_not_ok(1);
    DevBuf<uint32_t> d_inst(inst ? n : 0);
    uint32_t* di = inst ? d_inst.p : nullptr;
    run_inline_query(view, d_rays, d_hits, di, n, any, d_not_ok.p, nullptr);
    CWBVH_CUDA_CHECK(cudaDeviceSynchronize());
    std::vector<float> times;
    for (int i = 0; i < repeat; ++i) {
        CWBVH_CUDA_CHECK(cudaMemset(d_not_ok.p, 0, sizeof(unsigned long long)));
        float ms = 0;
        run_inline_query(view, d_rays, d_hits, di, n, any, d_not_ok.p, &ms);
        times.push_back(ms);
    }
    hits.resize(n);
    if (n) CWBVH_CUDA_CHECK(cudaMemcpy(hits.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost));
    if (inst) {
        inst->resize(n);
        if (n) CWBVH_CUDA_CHECK(cudaMemcpy(inst->data(), di, n * sizeof(uint32_t), cudaMemcpyDeviceToHost));
    }
    unsigned long long bad = 0;
    CWBVH_CUDA_CHECK(cudaMemcpy(&bad, d_not_ok.p, sizeof bad, cudaMemcpyDeviceToHost));
    not_ok = bad;
    std::sort(times.begin(), times.end());
    return times[times.size() / 2];
}

#ifdef CWBVH_HAVE_OPTIX
/// The OptiX peer timed as run_kernel times ours: one untimed warm-up, `repeat` timed
/// launches (events around optixLaunch alone), the hits of the last one.
double run_optix(OptixPeer& peer, const Ray* d_rays, Hit* d_hits, size_t n, bool any, int repeat,
                 std::vector<Hit>& hits) {
    peer.trace(d_rays, d_hits, n, any);
    std::vector<float> times;
    for (int i = 0; i < repeat; ++i) {
        float ms = 0;
        peer.trace(d_rays, d_hits, n, any, &ms);
        times.push_back(ms);
    }
    hits.resize(n);
    if (n) CWBVH_CUDA_CHECK(cudaMemcpy(hits.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost));
    std::sort(times.begin(), times.end());
    return times[times.size() / 2];
}
#endif

int usage() {
    std::fprintf(stderr,
                 "usage: cwbvh_gpu_check [--width W] [--height H] [--repeat R] [--views CATALOG] [--csv PATH]\n"
                 "                       [--compile-times FILE] [--no-optix] [--postpone-sweep P,P...] [--deadline-s N]\n"
                 "                       [--cpu-only] [SCENE.cwbvh...]\n"
                 "  rays: every catalog view of each scene (default camera for a scene not in the catalog),\n"
                 "  W x H (default 2048 x 2048) primary rays and diffuse bounces 1-4; R timed runs (default 5).\n"
                 "  no scene: a synthetic 20k-triangle scene (builds with the compiler only). --cpu-only: generate "
                 "rays and CPU reference only\n"
                 "  (exercises everything but the GPU; used where there is no device).\n"
                 "  --compile-times FILE: lines 'SCENE SECONDS' (scripts/gpu-check.sh), shown in the scene table.\n"
                 "  --no-optix: leave the OptiX peer out (built only with -DCWBVH_OPTIX_INCLUDE_DIR).\n"
                 "  --postpone-sweep P,P...: also time the CWBVH kernel (closest hit) at these triangle postponing\n"
                 "  thresholds (percent of active lanes, 0-100; the default 20 is the CWBVH row itself; the last\n"
                 "  --postpone-sweep given counts), hits checked as the others'.\n"
                 "  --deadline-s N: start no view after N seconds from the start (the first view always runs);\n"
                 "  the tables then cover what ran.\n"
                 "  ray sets of fewer than 1M rays are printed ('*') but kept out of the geometric means.\n"
                 "  two-level files (format 1.2): each beside the flattened file of the same stem (another folder);\n"
                 "  the two-level kernel then traces the flattened file's rays (compile time key: instanced:NAME).\n"
                 "  exit: 0 pass or SKIPPED (no CUDA device), 1 mismatch, 2 usage/IO/CUDA error or unusable device,\n"
                 "  4 no mismatch but --deadline-s stopped the check before every view ran (RESULT: PARTIAL)\n");
    return 2;
}

void print_table(const std::vector<Row>& rows) {
    std::printf("\n%-21s %-10s %-9s %-7s %10s %7s | %8s %8s %8s %7s %7s %7s %7s | %6s %6s %6s %6s %6s | %6s %6s %6s "
                "%6s %6s %5s %5s\n",
                "scene", "view", "rays", "query", "count", "hit%", "CW Mr/s", "B2 Mr/s", "OX Mr/s", "CW/B2", "CW/OX",
                "CW/ND", "CW/RN", "CW n/r", "CW t/r", "RN n/r", "B2 n/r", "B2 t/r", "CW mis", "B2 mis", "ND mis",
                "RN mis", "OX mis", "ties", "ovfl");
    bool small = false;
    for (const Row& r : rows) {
        const KernelResult &c = r.k[kCw], &b = r.k[kB2], &o = r.k[kOx], &d = r.k[kNd], &n = r.k[kRn];
        small = small || !r.in_means();
        auto ratio = [&](int k) { return fmt(r.ratio(k) > 0, "%.2fx", r.ratio(k)); };
        auto count = [](const KernelResult& x, uint64_t v) { return fmt(x.ran, "%.0f", double(v)); };
        std::printf("%-21s %-10s %-9s %-7s %9zu%c %6.1f%% | %8.1f %8s %8s %7s %7s %7s %7s | %6.1f %6.1f %6s %6s %6s | "
                    "%6llu %6s %6s %6s %6s %5llu %5llu\n",
                    r.scene.c_str(), r.view.c_str(), r.rays_kind.c_str(), r.query.c_str(), r.rays,
                    r.in_means() ? ' ' : '*', r.rays ? 100.0 * double(r.cpu_hits) / double(r.rays) : 0.0, c.mrays,
                    fmt(b.ran, "%.1f", b.mrays).c_str(), fmt(o.ran, "%.1f", o.mrays).c_str(), ratio(kB2).c_str(),
                    ratio(kOx).c_str(), ratio(kNd).c_str(), ratio(kRn).c_str(), c.nodes_per_ray, c.tris_per_ray,
                    fmt(n.ran, "%.1f", n.nodes_per_ray).c_str(), fmt(b.ran, "%.1f", b.nodes_per_ray).c_str(),
                    fmt(b.ran, "%.1f", b.tris_per_ray).c_str(), (unsigned long long)c.mismatches,
                    count(b, b.mismatches).c_str(), count(d, d.mismatches).c_str(), count(n, n.mismatches).c_str(),
                    count(o, o.mismatches).c_str(), (unsigned long long)(c.ties + b.ties + d.ties + n.ties),
                    (unsigned long long)(c.overflows + b.overflows + d.overflows + n.overflows));
    }
    if (small)
        std::printf("* fewer than %zu rays: printed, not in the geometric means\n", kMinRaysForMeans);
    std::printf("CW/ND, CW/RN: the CWBVH kernel over itself without deferred hit distances (ND, TraceOptions::defer_hits "
                "= false) and with the reference node test for every ray (RN, fast_node_test = false; RN n/r its node "
                "visits a ray); CW, ND and RN mis: hits not the CPU reference's, a failure\n");
    std::printf("OX mis: OptiX hits that disagree with the CPU reference beyond equal-t ties (t within %u ulps, "
                "hit vs miss); counted, not a failure\n", kOptixUlpBound);
}

/// Per scene: our file and its compile time beside OptiX's GAS and its build time.
void print_scene_table(const std::vector<Scene>& scenes) {
    std::printf("\n%-21s %10s | %9s %10s %8s %9s %7s | %9s %8s %8s %8s\n", "scene", "triangles", "file MiB",
                "compile s", "2L MiB", "2L cmp s", "CW B/t", "GAS MiB", "GAS B/t", "build ms", "cmpct ms");
    for (const Scene& s : scenes) {
        const double tri = double(std::max<uint64_t>(s.triangles, 1));
        const double cw_dev = double(s.nodes.size() * sizeof(CwbvhNode) + s.tris.size() * sizeof(TriangleRecord));
        const bool two = s.two.has_value();
        std::printf("%-21s %10llu | %9.1f %10s %8s %9s %7.1f | %9s %8s %8s %8s\n", s.name.c_str(),
                    (unsigned long long)s.triangles, double(s.file_bytes) / 1048576.0,
                    fmt(s.compile_s >= 0, "%.2f", s.compile_s).c_str(),
                    fmt(two, "%.1f", two ? double(s.two->file_bytes) / 1048576.0 : 0.0).c_str(),
                    fmt(two && s.two->compile_s >= 0, "%.2f", two ? s.two->compile_s : 0.0).c_str(), cw_dev / tri,
                    fmt(s.gas, "%.1f", double(s.gas_bytes) / 1048576.0).c_str(),
                    fmt(s.gas, "%.1f", double(s.gas_bytes) / tri).c_str(), fmt(s.gas, "%.1f", s.gas_build_ms).c_str(),
                    fmt(s.gas, "%.1f", s.gas_compact_ms).c_str());
    }
    std::printf("file: the .cwbvh (with the BVH2 section); compile s: cwbvhc wall time on this machine "
                "(scripts/gpu-check.sh); CW B/t: NODE + TRIS bytes per triangle (what the CWBVH kernel reads);\n"
                "2L: the scene's two-level (instanced) file and its compile time, where given; "
                "GAS: OptiX PREFER_FAST_TRACE + ALLOW_COMPACTION, compacted; build ms: optixAccelBuild, cmpct ms: "
                "optixAccelCompact (CUDA events)\n");
    for (const Scene& s : scenes) {
        if (!s.two) continue;
        const Instanced& t = *s.two;
        std::string compile = fmt(t.compile_s >= 0, "%.2f s", t.compile_s);
        if (t.compile_s > 0 && s.compile_s >= 0)
            compile += " (the flattened file's " + fmt(true, "%.2f s", s.compile_s) + ": " +
                       fmt(true, "%.1fx", s.compile_s / t.compile_s) + " faster)";
        const double dev = double(t.top.size() * sizeof(CwbvhNode) + t.inst.size() * sizeof(InstanceRecord) +
                                  t.meshes.size() * sizeof(MeshRecord) + t.nodes.size() * sizeof(CwbvhNode) +
                                  t.tris.size() * sizeof(TriangleRecord));
        std::printf("%s two-level: %zu meshes placed %zu times, %llu distinct / %llu instanced triangles; file %.2f "
                    "MiB = %.3fx the flattened file (as given: gpu-check.sh compiles it with --keep-sbvh, BVH2 "
                    "included); compile %s; device %.1f MiB (flattened CWBVH %.1f)\n",
                    s.name.c_str(), t.meshes.size(), t.inst.size(), (unsigned long long)t.triangles,
                    (unsigned long long)t.instanced_triangles, double(t.file_bytes) / 1048576.0,
                    double(t.file_bytes) / double(std::max<uint64_t>(s.file_bytes, 1)),
                    compile.c_str(), dev / 1048576.0,
                    double(s.nodes.size() * sizeof(CwbvhNode) + s.tris.size() * sizeof(TriangleRecord)) / 1048576.0);
    }
}

/// The two-level rows: the instanced file's kernel beside the flattened file's CWBVH
/// kernel on the same rays, and the comparisons.
void print_two_level_table(const std::vector<Row>& rows) {
    bool anyrow = false, small = false, gpu = false;
    for (const Row& r : rows) {
        anyrow = anyrow || r.tl.present;
        gpu = gpu || r.tl.flat_gpu;
    }
    if (!anyrow) return;
    std::printf("\nTwo-level (instanced file) vs flattened file, same rays:\n");
    std::printf("%-21s %-10s %-9s %-7s %10s %7s | %8s %8s %6s | %6s %6s %6s | %6s | %6s %5s %5s %5s %5s %5s %5s "
                "%8s\n",
                "scene", "view", "rays", "query", "count", "hit%", "2L Mr/s", "CW Mr/s", "2L/CW", "2L n/r", "2L t/r",
                "CW n/r", "2L mis", "disagr", "h/m", "edge", "t", "round", "src", "ties", "worst t");
    for (const Row& r : rows) {
        if (!r.tl.present) continue;
        const KernelResult &t = r.tl.k, &c = r.k[kCw];
        const FlatCompare& f = r.tl.flat;
        small = small || !r.in_means();
        std::printf("%-21s %-10s %-9s %-7s %9zu%c %6.1f%% | %8s %8s %6s | %6s %6s %6s | %6s | %6llu %5llu %5llu %5llu "
                    "%5llu %5llu %5llu %8.2g\n",
                    r.scene.c_str(), r.view.c_str(), r.rays_kind.c_str(), r.query.c_str(), r.rays,
                    r.in_means() ? ' ' : '*', r.rays ? 100.0 * double(r.tl.cpu_hits) / double(r.rays) : 0.0,
                    fmt(t.ran, "%.1f", t.mrays).c_str(), fmt(c.ran, "%.1f", c.mrays).c_str(),
                    fmt(r.tl_ratio() > 0, "%.2fx", r.tl_ratio()).c_str(), fmt(t.ran, "%.1f", t.nodes_per_ray).c_str(),
                    fmt(t.ran, "%.1f", t.tris_per_ray).c_str(), fmt(c.ran, "%.1f", c.nodes_per_ray).c_str(),
                    fmt(t.ran, "%.0f", double(t.mismatches)).c_str(), (unsigned long long)f.disagreeing,
                    (unsigned long long)f.hit_vs_miss, (unsigned long long)f.edge, (unsigned long long)f.t_far,
                    (unsigned long long)f.t_rounding, (unsigned long long)f.source, (unsigned long long)f.ties,
                    f.worst_rel);
    }
    if (small)
        std::printf("* fewer than %zu rays: printed, not in the geometric means\n", kMinRaysForMeans);
    std::printf("2L: the two-level kernel on the instanced file; CW: the CWBVH kernel on the flattened file; 2L mis: "
                "hits that trace_two_level_cpu refutes (closest: not its record bit for bit, nor an equal-t tie or "
                "the same triangle within 4 ulps; any: hit vs miss, or nearer than the closest hit; a failure);\n"
                "disagr: rays whose two-level hit disagrees with the flattened file's (%s): hit/miss (h/m), t beyond "
                "1e-5 relative (t), another source triangle at a t not close (src);\n"
                "counted apart, accepted: edge (hit vs miss, or another triangle farther away, the nearer hit within "
                "1e-5 of an edge), round (t beyond 1e-5 but within 16 u of the scene extent along the normal), ties "
                "(another source at a close t)\n",
                gpu ? "GPU kernels' hits" : "CPU references");
}

/// A CSV number cell: empty where the kernel did not run, else %.6g (both CSV writers).
std::string csv_num(bool ran, double v) {
    if (!ran) return std::string();
    char b[32];
    std::snprintf(b, sizeof b, "%.6g", v);
    return std::string(b);
}

/// The CSV's postpone_sweep cell: "P:ms:mismatches" per threshold, ';' between.
std::string postpone_cell(const Row& r) {
    std::string out;
    for (const auto& [pc, k] : r.postpone) {
        if (!k.ran) continue;
        if (!out.empty()) out += ';';
        out += std::to_string(pc) + ':' + csv_num(true, k.ms) + ':' + std::to_string(k.mismatches);
    }
    return out;
}

bool write_csv(const std::string& path, const std::vector<Row>& rows, const std::string& device, int width,
               int height, int repeat) {
    std::ofstream f(path);
    if (!f) return false;
    f << "scene,view,rays,query,width,height,count,cpu_hits,device,repeat,cwbvh_ms,cwbvh_mrays,bvh2_ms,bvh2_mrays,"
         "cwbvh_over_bvh2,cwbvh_nodes_per_ray,cwbvh_tris_per_ray,bvh2_nodes_per_ray,bvh2_tris_per_ray,"
         "cwbvh_mismatches,bvh2_mismatches,cwbvh_ties,bvh2_ties,cwbvh_overflows,bvh2_overflows,"
         "optix_ms,optix_mrays,cwbvh_over_optix,optix_mismatches,optix_hit_vs_miss,optix_ties,in_means,"
         "inline_ms,inline_mrays,inline_over_cwbvh,inline_mismatches,inline_not_ok,nodefer_ms,nodefer_mrays,"
         "cwbvh_over_nodefer,nodefer_mismatches,refnode_ms,refnode_mrays,cwbvh_over_refnode,refnode_nodes_per_ray,"
         "refnode_mismatches,postpone_sweep\n";
    const auto& num = csv_num;
    auto cnt = [](bool ran, uint64_t v) { return ran ? std::to_string(v) : std::string(); };
    for (const Row& r : rows) {
        const KernelResult &c = r.k[kCw], &b = r.k[kB2], &o = r.k[kOx], &d = r.k[kNd], &n = r.k[kRn];
        f << r.scene << ',' << r.view << ',' << r.rays_kind << ',' << r.query << ',' << width << ',' << height << ','
          << r.rays << ',' << r.cpu_hits << ",\"" << device << "\"," << repeat << ',' << num(c.ran, c.ms) << ','
          << num(c.ran, c.mrays) << ',' << num(b.ran, b.ms) << ',' << num(b.ran, b.mrays) << ','
          << num(r.ratio(kB2) > 0, r.ratio(kB2)) << ',' << num(c.ran, c.nodes_per_ray) << ','
          << num(c.ran, c.tris_per_ray) << ',' << num(b.ran, b.nodes_per_ray) << ',' << num(b.ran, b.tris_per_ray)
          << ',' << cnt(c.ran, c.mismatches) << ',' << cnt(b.ran, b.mismatches) << ',' << cnt(c.ran, c.ties) << ','
          << cnt(b.ran, b.ties) << ',' << cnt(c.ran, c.overflows) << ',' << cnt(b.ran, b.overflows) << ','
          << num(o.ran, o.ms) << ',' << num(o.ran, o.mrays) << ',' << num(r.ratio(kOx) > 0, r.ratio(kOx)) << ','
          << cnt(o.ran, o.mismatches) << ',' << cnt(o.ran, o.hit_vs_miss) << ',' << cnt(o.ran, o.ties) << ','
          << (r.in_means() ? 1 : 0) << ',' << num(r.inl.ran, r.inl.ms) << ',' << num(r.inl.ran, r.inl.mrays)
          << ',' << num(r.inl.ran && c.ran && c.mrays > 0, c.mrays > 0 ? r.inl.mrays / c.mrays : 0.0) << ','
          << cnt(r.inl.ran, r.inl.mismatches) << ',' << cnt(r.inl.ran, r.inl.overflows) << ',' << num(d.ran, d.ms)
          << ',' << num(d.ran, d.mrays) << ',' << num(r.ratio(kNd) > 0, r.ratio(kNd)) << ','
          << cnt(d.ran, d.mismatches) << ',' << num(n.ran, n.ms) << ',' << num(n.ran, n.mrays) << ','
          << num(r.ratio(kRn) > 0, r.ratio(kRn)) << ',' << num(n.ran, n.nodes_per_ray) << ','
          << cnt(n.ran, n.mismatches) << ',' << postpone_cell(r) << '\n';
    }
    return bool(f);
}

/// The two-level rows (--csv PATH: PATH's stem + "_two_level.csv").
bool write_two_level_csv(const std::string& path, const std::vector<Row>& rows, const std::string& device, int width,
                         int height, int repeat) {
    std::ofstream f(path);
    if (!f) return false;
    f << "scene,view,rays,query,width,height,count,device,repeat,cpu_hits_flat,cpu_hits_two_level,two_level_ms,"
         "two_level_mrays,cwbvh_ms,cwbvh_mrays,two_level_over_cwbvh,two_level_nodes_per_ray,two_level_tris_per_ray,"
         "two_level_mismatches,two_level_near,two_level_ties,two_level_not_bitwise,two_level_overflows,flat_compared,flat_disagreeing,flat_hit_vs_miss,"
         "flat_edge,flat_t,flat_t_rounding,flat_source,flat_ties,flat_worst_rel,in_means,inline_ms,inline_mrays,"
         "inline_mismatches\n";
    const auto& num = csv_num;
    for (const Row& r : rows) {
        if (!r.tl.present) continue;
        const KernelResult &t = r.tl.k, &c = r.k[kCw];
        const FlatCompare& x = r.tl.flat;
        f << r.scene << ',' << r.view << ',' << r.rays_kind << ',' << r.query << ',' << width << ',' << height << ','
          << r.rays << ",\"" << device << "\"," << repeat << ',' << r.cpu_hits << ',' << r.tl.cpu_hits << ','
          << num(t.ran, t.ms) << ',' << num(t.ran, t.mrays) << ',' << num(c.ran, c.ms) << ',' << num(c.ran, c.mrays)
          << ',' << num(r.tl_ratio() > 0, r.tl_ratio()) << ',' << num(t.ran, t.nodes_per_ray) << ','
          << num(t.ran, t.tris_per_ray) << ',' << (t.ran ? std::to_string(t.mismatches) : std::string()) << ','
          << (t.ran ? std::to_string(r.tl.cmp.near) : std::string()) << ','
          << (t.ran ? std::to_string(r.tl.cmp.ties) : std::string()) << ','
          << (t.ran ? std::to_string(r.tl.cmp.not_bitwise) : std::string()) << ','
          << (t.ran ? std::to_string(t.overflows) : std::string()) << ',' << (r.tl.flat_gpu ? "gpu" : "cpu") << ','
          << x.disagreeing << ',' << x.hit_vs_miss << ',' << x.edge << ',' << x.t_far << ',' << x.t_rounding << ','
          << x.source << ',' << x.ties << ',' << num(true, x.worst_rel) << ',' << (r.in_means() ? 1 : 0) << ','
          << num(r.tl.inl.ran, r.tl.inl.ms) << ',' << num(r.tl.inl.ran, r.tl.inl.mrays) << ','
          << (r.tl.inl.ran ? std::to_string(r.tl.inl.mismatches) : std::string()) << '\n';
    }
    return bool(f);
}

/// PATH's stem + "_two_level.csv" (PATH without ".csv": PATH + "_two_level.csv").
std::string two_level_csv_path(const std::string& csv) {
    const size_t slash = csv.find_last_of('/');
    const size_t base = slash == std::string::npos ? 0 : slash + 1;
    if (csv.size() > base + 4 && csv.compare(csv.size() - 4, 4, ".csv") == 0)
        return csv.substr(0, csv.size() - 4) + "_two_level.csv";
    return csv + "_two_level.csv";
}

/// --compile-times: "SCENE SECONDS" per line (scripts/gpu-check.sh writes it).
bool read_compile_times(const std::string& path, std::map<std::string, double>& out) {
    // A regular file of at most 1 MiB (file_io.h: no FIFO or device, bounded before allocating).
    std::vector<uint8_t> bytes;
    if (!read_regular_file(path, uint64_t(1) << 20, bytes).ok()) return false;
    std::istringstream f(std::string(bytes.begin(), bytes.end()));
    std::string line;
    while (std::getline(f, line)) {
        std::istringstream in(line);
        std::string name, rest;
        double sec = 0;
        if (!(in >> name)) continue;  // blank line
        if (!(in >> sec) || in >> rest || !(sec >= 0)) return false;
        out[name] = sec;
    }
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    // Line-buffered even into a pipe or file (gpu-check.sh tees it): a run cut off by the
    // device tool's time limit still leaves every line it printed.
    std::setvbuf(stdout, nullptr, _IOLBF, 0);
    const auto start = std::chrono::steady_clock::now();
    int width = 2048, height = 2048, repeat = 5, deadline_s = 0;
    bool cpu_only = false, no_optix = false;
    std::vector<uint32_t> postpone_sweep;
    std::string views_path, csv_path, compile_times_path;
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
        else if (a == "--deadline-s") { if (!num(deadline_s, 7 * 86400)) return usage(); }
        else if (a == "--views") { if (!str(views_path)) return usage(); }
        else if (a == "--csv") { if (!str(csv_path)) return usage(); }
        else if (a == "--compile-times") { if (!str(compile_times_path)) return usage(); }
        else if (a == "--no-optix") no_optix = true;
        else if (a == "--postpone-sweep") {  // the last one given counts (gpu-check.sh passes a default first)
            if (i + 1 >= argc || !*argv[i + 1]) return usage();
            postpone_sweep.clear();
            std::istringstream in(argv[++i]);
            std::string item;
            while (std::getline(in, item, ',')) {
                char* end = nullptr;
                const long x = std::strtol(item.c_str(), &end, 10);
                if (item.empty() || *end != '\0' || x < 0 || x > 100) return usage();
                // The default is the production kernel's own row: not timed twice.
                if (uint32_t(x) != kDefaultPostponePercent &&
                    std::find(postpone_sweep.begin(), postpone_sweep.end(), uint32_t(x)) == postpone_sweep.end())
                    postpone_sweep.push_back(uint32_t(x));
            }
        }
        else if (a == "--cpu-only") cpu_only = true;
        else if (a == "-h" || a == "--help") return usage();
        else if (!a.empty() && a[0] == '-') return usage();
        else paths.push_back(a);
    }
    // The tables never overwrite an input (the scenes, the catalog, the compile times)
    // or each other.
    if (!csv_path.empty()) {
        std::vector<std::string> inputs = paths;
        if (!views_path.empty()) inputs.push_back(views_path);
        if (!compile_times_path.empty()) inputs.push_back(compile_times_path);
        Result out = check_output_path(csv_path, inputs);
        if (out.ok()) {
            inputs.push_back(csv_path);
            out = check_output_path(two_level_csv_path(csv_path), inputs);
        }
        if (!out.ok()) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: %s\n", out.message.c_str());
            return 2;
        }
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

    std::map<std::string, double> compile_times;
    if (!compile_times_path.empty() && !read_compile_times(compile_times_path, compile_times)) {
        std::fprintf(stderr, "cwbvh_gpu_check: error: %s: cannot read 'SCENE SECONDS' lines\n",
                     compile_times_path.c_str());
        return 2;
    }

    std::vector<Scene> scenes;
    if (paths.empty()) {
#ifdef CWBVH_HAVE_SYNTHETIC
        SyntheticOptions so;
        so.triangles = 20000;
        SceneData sd = make_synthetic_scene(so);
        Scene s{"synthetic-20k", std::move(sd.nodes), std::move(sd.triangles), std::move(sd.bvh2), sd.bounds};
        s.triangles = so.triangles;
        scenes.push_back(std::move(s));
#else
        std::fprintf(stderr, "cwbvh_gpu_check: error: no scene given (this build has no compiler core, so no "
                             "synthetic scene: pass SCENE.cwbvh files)\n");
        return 2;
#endif
    }
    std::vector<Instanced> instanced;  // two-level files, paired with their flattened scene below
    for (const std::string& p : paths) {
        Expected<File> f = File::open(p);
        if (!f.ok()) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: %s\n", f.error().describe().c_str());
            return 2;
        }
        if (f->is_two_level()) {
            Instanced t;
            t.path = p;
            t.top.assign(f->top_nodes().begin(), f->top_nodes().end());
            t.nodes.assign(f->nodes().begin(), f->nodes().end());
            t.tris.assign(f->triangles().begin(), f->triangles().end());
            t.inst.assign(f->instances().begin(), f->instances().end());
            t.meshes.assign(f->meshes().begin(), f->meshes().end());
            t.pmap.assign(f->source_ranges().begin(), f->source_ranges().end());
            t.triangles = f->stored_triangle_count();
            t.instanced_triangles = f->instanced_triangle_count();
            t.file_bytes = f->bytes().size();
            if (const auto it = compile_times.find("instanced:" + scene_key(p)); it != compile_times.end())
                t.compile_s = it->second;
            instanced.push_back(std::move(t));
            continue;
        }
        Scene s;
        s.name = scene_key(p);
        s.nodes.assign(f->nodes().begin(), f->nodes().end());
        s.tris.assign(f->triangles().begin(), f->triangles().end());
        s.bvh2.assign(f->bvh2().begin(), f->bvh2().end());
        if (f->bounds()) s.bounds = *f->bounds();
        s.triangles = f->stored_triangle_count();
        s.file_bytes = f->bytes().size();
        s.pmap.assign(f->source_ranges().begin(), f->source_ranges().end());
        if (const auto it = compile_times.find(s.name); it != compile_times.end()) s.compile_s = it->second;
        scenes.push_back(std::move(s));
    }
    for (Instanced& t : instanced) {
        const std::string key = scene_key(t.path);
        Scene* partner = nullptr;
        for (Scene& s : scenes)
            if (s.name == key) partner = &s;
        if (!partner) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: %s: a two-level file needs the flattened file of the same "
                                 "scene beside it (%s.cwbvh in another folder, cwbvhc --flatten): its rays come from "
                                 "that file\n", t.path.c_str(), key.c_str());
            return 2;
        }
        if (partner->two) {
            std::fprintf(stderr, "cwbvh_gpu_check: error: %s: a second two-level file for scene %s (first: %s)\n",
                         t.path.c_str(), key.c_str(), partner->two->path.c_str());
            return 2;
        }
        if (t.instanced_triangles != partner->triangles)
            std::printf("%s: the two-level file places %llu triangles, the flattened file stores %llu\n", key.c_str(),
                        (unsigned long long)t.instanced_triangles, (unsigned long long)partner->triangles);
        partner->two = std::move(t);
    }

    std::vector<Row> rows;
    std::string device_name = "cpu-only";
    bool failed = false;
    std::string cut;  // --deadline-s: where the check stopped, empty when every view ran
    try {
        if (have_gpu) {
            cudaDeviceProp prop{};
            CWBVH_CUDA_CHECK(cudaGetDeviceProperties(&prop, 0));
            device_name = prop.name;
            std::printf("device: %s (sm_%d%d, %d SMs)\n", prop.name, prop.major, prop.minor,
                        prop.multiProcessorCount);
            KernelInfo info[16];
            const int nk = kernel_info(info, 16);
            for (int k = 0; k < nk; ++k)
                std::printf("kernel %-32s regs %3d  local %5zu B  shared %6zu B  ptx %d  sass %d\n", info[k].name,
                            info[k].registers, info[k].local_bytes, info[k].shared_bytes, info[k].ptx_version,
                            info[k].binary_version);
            // The fast node test's half arithmetic, the per-ray set-up and the reference
            // node test on this device against the host (fast_node_selfcheck.h), on each
            // scene's own nodes: a mismatch fails the check before any timing.
            for (size_t i = 0; i < scenes.size(); ++i) {
                const FastNodeSelfCheck sc = run_fast_node_selfcheck(scenes[i].nodes.data(), scenes[i].nodes.size(),
                                                                     i + 1, i == 0 ? (size_t(1) << 20) : 0,
                                                                     size_t(1) << 16);
                if (!sc.ran) throw std::runtime_error("fast node self-check: " + sc.error);
                std::printf("fast node test, device vs host emulation, %s: %llu (node, ray) pairs (%llu hit), %llu "
                            "differ; %llu half/rounding cases, %llu differ\n",
                            scenes[i].name.c_str(), (unsigned long long)sc.node_pairs,
                            (unsigned long long)sc.node_pairs_hit, (unsigned long long)sc.node_mismatches,
                            (unsigned long long)sc.fp16_cases, (unsigned long long)sc.fp16_mismatches);
                for (const std::string& d : sc.differences) std::printf("  differs: %s\n", d.c_str());
                std::printf("reference node test, device vs host, %s: %llu of the pairs differ (an fma contraction "
                            "may move a box edge by an ulp: at most 1 in 10,000 allowed)\n",
                            scenes[i].name.c_str(), (unsigned long long)sc.reference_differences);
                for (const std::string& d : sc.reference_lines) std::printf("  differs: %s\n", d.c_str());
                if (sc.node_mismatches || sc.fp16_mismatches || !sc.reference_within_contraction()) failed = true;
            }
        }
        // The OptiX peer: one line saying why when it does not run.
#ifdef CWBVH_HAVE_OPTIX
        std::unique_ptr<OptixPeer> optix;
        if (have_gpu && !no_optix) {
            std::string optix_why;
            optix = OptixPeer::create(optix_why);
            if (optix) std::printf("optix: %s, libnvoptix from the driver\n", OptixPeer::version().c_str());
            else std::printf("optix: skipped: %s\n", optix_why.c_str());
        } else if (have_gpu) {
            std::printf("optix: skipped: --no-optix\n");
        }
#else
        if (have_gpu) std::printf("optix: skipped: built without the OptiX 9.0 headers (-DCWBVH_OPTIX_INCLUDE_DIR; "
                                  "scripts/gpu-check.sh: gpu_inputs/optix/include)\n");
        (void)no_optix;
#endif
        std::printf("rays: %dx%d per view, diffuse bounces 1-%d (paths end when they escape), seed %u, "
                    "%d timed runs\n", width, height, kBounces, kSeed, repeat);
        // --deadline-s: checked before each scene and each view, so that a run under a time
        // limit (the device tool's 10 minutes a command) still prints its tables. The first
        // view always runs: a run that checked nothing must not end as a partial pass.
        auto past_deadline = [&](const std::string& next) {
            if (deadline_s <= 0 || !cut.empty()) return !cut.empty();
            if (rows.empty()) return false;
            const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (t < double(deadline_s)) return false;
            char b[64];
            std::snprintf(b, sizeof b, " after %.0f s (--deadline-s %d)", t, deadline_s);
            cut = next + b;
            return true;
        };
        for (Scene& s : scenes) {
            if (past_deadline("scene " + s.name)) break;
            const PrimTable table(s.tris.data(), s.tris.size());
            std::optional<DeviceScene> ds, ds2;  // ds2: the two-level file (s.two)
            // Two-level vs flattened (hit_compare.h): the same source triangle, and the
            // flattened triangle's normal against the ray for the rounding bound.
            const double slack = flat_rounding_slack([&] {
                double e = 0;
                for (int a = 0; a < 3; ++a) e = std::max({e, std::fabs(double(s.bounds.lo[a])),
                                                          std::fabs(double(s.bounds.hi[a]))});
                return e;
            }());
            auto same_source = [&](uint32_t two_prim, uint32_t flat_prim) {
                const auto a = find_source(s.two->pmap, two_prim), b = find_source(s.pmap, flat_prim);
                return a && b && a->input == b->input && a->mesh == b->mesh && a->primitive == b->primitive &&
                       a->triangle == b->triangle;
            };
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
                if (s.two) {
                    const Instanced& t = *s.two;
                    auto up2 = DeviceScene::upload(t.nodes.data(), t.nodes.size(), t.tris.data(), t.tris.size(),
                                                   nullptr, 0, t.sections(), uo);
                    if (!up2.ok()) throw std::runtime_error(t.path + ": " + up2.error().message);
                    ds2 = std::move(up2.value());
                    std::printf("%s (two-level, %s): upload %.1f MiB (top level %.2f MiB): pinned staging %.2f ms\n",
                                s.name.c_str(), t.path.c_str(), double(ds2->upload_stats().bytes) / 1048576.0,
                                double(ds2->top_level_bytes()) / 1048576.0, ds2->upload_stats().seconds * 1e3);
                }
#ifdef CWBVH_HAVE_OPTIX
                OptixGasInfo gi;
                if (optix) {
                    try {
                        gi = optix->build(s.tris.data(), s.tris.size());
                    } catch (const CudaError&) {
                        throw;  // the device may be unusable now: fail as any CUDA error does
                    } catch (const std::exception& e) {  // OptiX's own error: our check goes on
                        std::printf("optix: stopped (%s: GAS build): %s\n", s.name.c_str(), e.what());
                        optix.reset();
                    }
                }
                if (optix) {
                    s.gas = true;
                    s.gas_bytes = gi.gas_bytes;
                    s.gas_build_ms = gi.build_ms;
                    s.gas_compact_ms = gi.compact_ms;
                    std::printf("%s: OptiX GAS %llu triangles: build %.1f ms, compact %.1f ms, %.1f MiB (%.1f before "
                                "compaction, %.1f B/triangle)\n",
                                s.name.c_str(), (unsigned long long)gi.triangles, gi.build_ms, gi.compact_ms,
                                double(gi.gas_bytes) / 1048576.0, double(gi.uncompacted_bytes) / 1048576.0,
                                double(gi.gas_bytes) / double(std::max<uint64_t>(gi.triangles, 1)));
                }
#endif
            }

            for (const View& view : benchmark_views(catalog, s.name, s.bounds)) {
                if (past_deadline("scene " + s.name + " view " + view.name)) break;
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
                    // The instanced file on the same rays: CPU reference (closest, any).
                    std::vector<Hit> ref2, ref2_any;
                    std::vector<uint32_t> inst2, inst2_any;
                    CpuTraceStats ts2, ta2;
                    if (s.two) {
                        const TwoLevelScene tv = s.two->view();
                        ref2.resize(rays.size());
                        ref2_any.resize(rays.size());
                        inst2.resize(rays.size());
                        inst2_any.resize(rays.size());
                        CpuTraceOptions o2;
                        ts2 = trace_two_level_cpu(tv, rays.data(), ref2.data(), inst2.data(), rays.size(), o2);
                        o2.mode = HitMode::kAny;
                        ta2 = trace_two_level_cpu(tv, rays.data(), ref2_any.data(), inst2_any.data(), rays.size(), o2);
                        std::printf("  %-9s %9s two-level %9llu hits (%5.1f%%), any-hit %9llu, CPU %.2f Mrays/s\n", "",
                                    "", (unsigned long long)ts2.hits,
                                    rays.empty() ? 0.0 : 100.0 * double(ts2.hits) / double(rays.size()),
                                    (unsigned long long)ta2.hits,
                                    ts2.seconds > 0 ? double(rays.size()) / ts2.seconds / 1e6 : 0.0);
                        if (ta2.hits != ts2.hits || ts2.bad_indices + ta2.bad_indices) {
                            std::printf("  MISMATCH %s %s %s two-level CPU: closest hit %llu rays, any hit %llu, bad "
                                        "indices %llu\n",
                                        s.name.c_str(), view.name.c_str(), kind_name(bounce),
                                        (unsigned long long)ts2.hits, (unsigned long long)ta2.hits,
                                        (unsigned long long)(ts2.bad_indices + ta2.bad_indices));
                            failed = true;
                        }
                    }
                    // Prints one query's two-level line (after the comparisons are in).
                    auto two_level_line = [&](const Row& r) {
                        const bool any = r.query == "any";
                        if (r.tl.k.ran)
                            std::printf("  2L %-7s %8.1f Mrays/s, flattened CWBVH %8s: %s; %llu mismatches; inline "
                                        "query %s Mrays/s; vs flattened (GPU): %s\n",
                                        r.query.c_str(), r.tl.k.mrays,
                                        fmt(r.k[kCw].ran, "%.1f", r.k[kCw].mrays).c_str(),
                                        fmt(r.tl_ratio() > 0, "%.2fx", r.tl_ratio()).c_str(),
                                        (unsigned long long)r.tl.k.mismatches,
                                        fmt(r.tl.inl.ran, "%.1f", r.tl.inl.mrays).c_str(),
                                        describe(r.tl.flat, any).c_str());
                        else
                            std::printf("  2L %-7s vs flattened (CPU): %s\n", r.query.c_str(),
                                        describe(r.tl.flat, any).c_str());
                    };
                    auto flat_compare = [&](const std::vector<Hit>& two, const std::vector<Hit>& flat, bool any) {
                        return compare_with_flattened(two, flat, any, slack, same_source,
                                                      [&](size_t i, uint32_t prim) -> double {
                                                          const TriangleRecord* tri = table.find(prim);
                                                          float n[3];
                                                          if (!tri || !geometric_normal(*tri, n)) return -1.0;
                                                          return std::fabs(double(n[0]) * rays[i].dir[0] +
                                                                           double(n[1]) * rays[i].dir[1] +
                                                                           double(n[2]) * rays[i].dir[2]);
                                                      });
                    };
                    // The first ray of a two-level vs flattened disagreement, for the log.
                    auto first_disagreement = [&](const FlatCompare& c, const std::vector<Hit>& two,
                                                  const std::vector<uint32_t>& inst, const std::vector<Hit>& flat) {
                        if (c.first_bad < 0) return;
                        const size_t i = size_t(c.first_bad);
                        auto src = [](const std::vector<SourceRange>& pm, uint32_t prim) {
                            const auto r = prim == kMissPrim ? std::nullopt : find_source(pm, prim);
                            char b[64];
                            if (r) std::snprintf(b, sizeof b, "%u/%u/%u/%u", r->input, r->mesh, r->primitive,
                                                 r->triangle);
                            else std::snprintf(b, sizeof b, "-");
                            return std::string(b);
                        };
                        std::printf("    first disagreement: ray %zu: two-level inst %u prim %u (source %s) t %.9g "
                                    "u %.6g v %.6g; flattened prim %u (source %s) t %.9g u %.6g v %.6g\n",
                                    i, inst[i], two[i].prim, src(s.two->pmap, two[i].prim).c_str(), double(two[i].t),
                                    double(two[i].u), double(two[i].v), flat[i].prim, src(s.pmap, flat[i].prim).c_str(),
                                    double(flat[i].t), double(flat[i].u), double(flat[i].v));
                    };
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
                        if (s.two) {
                            const CpuTraceStats& t2 = any ? ta2 : ts2;
                            r.tl.present = true;
                            r.tl.cpu_hits = t2.hits;
                            r.tl.cpu_mrays = t2.seconds > 0 ? double(rays.size()) / t2.seconds / 1e6 : 0.0;
                            if (!have_gpu || rays.empty()) {  // the CPU references (no GPU, or --cpu-only)
                                r.tl.flat = flat_compare(any ? ref2_any : ref2, any ? ref_any : ref, any != 0);
                                two_level_line(r);
                                first_disagreement(r.tl.flat, any ? ref2_any : ref2, any ? inst2_any : inst2,
                                                   any ? ref_any : ref);
                            }
                        }
                        rows.push_back(r);
                    }
                    if (have_gpu && !rays.empty()) {
                        DevBuf<Ray> d_rays(rays.size());
                        DevBuf<Hit> d_hits(rays.size());
                        CWBVH_CUDA_CHECK(cudaMemcpy(d_rays.p, rays.data(), rays.size() * sizeof(Ray),
                                                    cudaMemcpyHostToDevice));
                        for (int any = 0; any < 2; ++any) {
                            Row& r = rows[rows.size() - 2 + size_t(any)];
#ifdef CWBVH_HAVE_OPTIX
                            std::vector<Hit> ox_hits;
                            double ox_ms = 0;
                            if (optix) {
                                try {
                                    ox_ms = run_optix(*optix, d_rays.p, d_hits.p, rays.size(), any != 0, repeat,
                                                      ox_hits);
                                } catch (const CudaError&) {
                                    throw;
                                } catch (const std::exception& e) {
                                    std::printf("optix: stopped (%s %s %s): %s\n", s.name.c_str(), view.name.c_str(),
                                                kind_name(bounce), e.what());
                                    optix.reset();
                                }
                            }
                            if (optix) {
                                const HitCompare c =
                                    compare_hits(ox_hits, any ? ref_any : ref, any != 0, kOptixUlpBound);
                                KernelResult& kr = r.k[kOx];
                                kr.ran = true;
                                kr.ms = ox_ms;
                                kr.mrays = ox_ms > 0 ? double(rays.size()) / (ox_ms * 1e3) : 0.0;
                                kr.mismatches = c.mismatches;
                                kr.hit_vs_miss = c.hit_vs_miss;
                                kr.ties = c.ties;
                            }
#endif
                            std::vector<Hit> cw_hits;  // the flattened file's CWBVH kernel (two-level comparison)
                            // One of our kernels on these rays, its hits checked against the CPU
                            // reference (a mismatch or bad index fails the check); `hits` keeps them.
                            auto run_checked = [&](Kernel which, const char* kname, uint32_t postpone,
                                                   std::vector<Hit>& hits) {
                                DeviceTraceStats st;
                                const double ms = run_kernel(*ds, which, d_rays.p, d_hits.p, rays.size(), any != 0,
                                                             repeat, hits, st, nullptr, nullptr, postpone);
                                const std::vector<Hit>& cpu = any ? ref_any : ref;
                                const HitCompare c = compare_hits(hits, cpu, any != 0, kKernelUlpBound);
                                KernelResult kr;
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
                                                    view.name.c_str(), r.rays_kind.c_str(), r.query.c_str(), kname,
                                                    (unsigned long long)st.bad_indices);
                                    if (c.first_bad >= 0) {
                                        const size_t i = size_t(c.first_bad);
                                        std::printf("  MISMATCH %s %s %s %s %s ray %zu: gpu prim %u t %.9g, cpu prim "
                                                    "%u t %.9g (%llu mismatches)\n",
                                                    s.name.c_str(), view.name.c_str(), r.rays_kind.c_str(),
                                                    r.query.c_str(), kname, i, hits[i].prim,
                                                    double(hits[i].t), cpu[i].prim, double(cpu[i].t),
                                                    (unsigned long long)c.mismatches);
                                    }
                                }
                                return kr;
                            };
                            // The CWBVH kernel, BVH2, and the CWBVH kernel's A/Bs: without deferred
                            // hits, with the reference node test.
                            struct Timed {
                                int slot;  // Row::k
                                Kernel kernel;
                                const char* name;
                            };
                            static constexpr Timed kTimed[] = {{kCw, Kernel::kCwbvh, "cwbvh"},
                                                               {kB2, Kernel::kBvh2, "bvh2"},
                                                               {kNd, Kernel::kCwbvhNoDefer, "cwbvh_nodefer"},
                                                               {kRn, Kernel::kCwbvhRefNode, "cwbvh_refnode"}};
                            for (const Timed& t : kTimed) {
                                if (t.kernel == Kernel::kBvh2 && !ds->has_bvh2()) continue;
                                std::vector<Hit> hits;
                                r.k[t.slot] = run_checked(t.kernel, t.name, kDefaultPostponePercent, hits);
                                if (t.slot == kCw) cw_hits = std::move(hits);
                            }
                            // --postpone-sweep: the CWBVH kernel at other thresholds, closest hit.
                            for (const uint32_t pc : any ? std::vector<uint32_t>{} : postpone_sweep) {
                                char kname[40];
                                std::snprintf(kname, sizeof kname, "cwbvh_postpone%u", pc);
                                std::vector<Hit> hits;
                                r.postpone.emplace_back(pc, run_checked(Kernel::kCwbvh, kname, pc, hits));
                            }
                            // The inline query, one thread per ray, on `qview` (the flattened file, or
                            // the instanced one with its instances), checked with compare_query
                            // against `cpu` (closest or any hit, as the query) and `closest`.
                            auto inline_checked = [&](const SceneView& qview, const std::vector<Hit>& cpu,
                                                      const std::vector<uint32_t>& cpu_inst,
                                                      const std::vector<Hit>& closest, KernelResult& kr,
                                                      QueryCompare& cmp) {
                                const bool two = qview.two_level();
                                std::vector<Hit> hits;
                                std::vector<uint32_t> inst;
                                uint64_t not_ok = 0;
                                kr.ms = run_inline(qview, d_rays.p, d_hits.p, rays.size(), any != 0, repeat, hits,
                                                   not_ok, two ? &inst : nullptr);
                                if (!two) inst.assign(rays.size(), kInvalidIndex);
                                kr.ran = true;
                                kr.mrays = kr.ms > 0 ? double(rays.size()) / (kr.ms * 1e3) : 0.0;
                                cmp = compare_query(hits, inst, cpu, cpu_inst, any != 0, closest);
                                kr.mismatches = cmp.mismatches;
                                kr.ties = cmp.ties;
                                kr.overflows = not_ok;
                                if (kr.mismatches == 0 && not_ok == 0) return;
                                failed = true;
                                std::printf("  INLINE QUERY %s %s %s %s%s: %s; %llu overflows or bad indices\n",
                                            s.name.c_str(), view.name.c_str(), r.rays_kind.c_str(), r.query.c_str(),
                                            two ? " two-level" : "", describe(cmp).c_str(),
                                            (unsigned long long)not_ok);
                                if (cmp.first_bad >= 0) {
                                    const size_t i = size_t(cmp.first_bad);
                                    std::printf("    first: ray %zu: gpu inst %u prim %u t %.9g u %.9g v %.9g, cpu "
                                                "inst %u prim %u t %.9g u %.9g v %.9g\n",
                                                i, inst[i], hits[i].prim, double(hits[i].t), double(hits[i].u),
                                                double(hits[i].v), cpu_inst[i], cpu[i].prim, double(cpu[i].t),
                                                double(cpu[i].u), double(cpu[i].v));
                                }
                            };
                            if (!ds->has_two_level()) {
                                const std::vector<uint32_t> none(rays.size(), kInvalidIndex);
                                inline_checked(ds->view(), any ? ref_any : ref, none, ref, r.inl, r.inl_cmp);
                            }
                            if (ds2) {  // the two-level kernel on the instanced file, the same rays
                                DevBuf<uint32_t> d_inst(rays.size());
                                std::vector<Hit> hits;
                                std::vector<uint32_t> inst;
                                DeviceTraceStats st;
                                const double ms = run_kernel(*ds2, Kernel::kTwoLevel, d_rays.p, d_hits.p, rays.size(),
                                                             any != 0, repeat, hits, st, d_inst.p, &inst);
                                KernelResult& kr = r.tl.k;
                                r.tl.cmp = compare_query(hits, inst, any ? ref2_any : ref2, any ? inst2_any : inst2,
                                                         any != 0, ref2);
                                kr.mismatches = r.tl.cmp.mismatches;
                                kr.ties = r.tl.cmp.ties;
                                const int64_t first = r.tl.cmp.first_bad;
                                kr.ran = true;
                                kr.ms = ms;
                                kr.mrays = ms > 0 ? double(rays.size()) / (ms * 1e3) : 0.0;
                                kr.nodes_per_ray = double(st.nodes_visited) / double(rays.size());
                                kr.tris_per_ray = double(st.triangles_tested) / double(rays.size());
                                kr.overflows = st.stack_overflows;
                                kr.bad_indices = st.bad_indices;
                                const std::vector<Hit>& flat_hits = cw_hits.empty() ? (any ? ref_any : ref) : cw_hits;
                                r.tl.flat = flat_compare(hits, flat_hits, any != 0);
                                r.tl.flat_gpu = !cw_hits.empty();
                                inline_checked(ds2->view(), any ? ref2_any : ref2, any ? inst2_any : inst2, ref2,
                                               r.tl.inl, r.tl.inl_cmp);
                                two_level_line(r);
                                first_disagreement(r.tl.flat, hits, inst, flat_hits);
                                if (kr.mismatches || st.bad_indices) {
                                    failed = true;
                                    if (st.bad_indices)
                                        std::printf("  BAD INDICES %s %s %s %s two-level: %llu\n", s.name.c_str(),
                                                    view.name.c_str(), r.rays_kind.c_str(), r.query.c_str(),
                                                    (unsigned long long)st.bad_indices);
                                    if (first >= 0) {
                                        const size_t i = size_t(first);
                                        const std::vector<Hit>& cpu = any ? ref2_any : ref2;
                                        const std::vector<uint32_t>& ci = any ? inst2_any : inst2;
                                        std::printf("  MISMATCH %s %s %s %s two-level ray %zu: gpu inst %u prim %u t "
                                                    "%.9g u %.9g v %.9g, cpu inst %u prim %u t %.9g u %.9g v %.9g "
                                                    "(%s)\n",
                                                    s.name.c_str(), view.name.c_str(), r.rays_kind.c_str(),
                                                    r.query.c_str(), i, inst[i], hits[i].prim, double(hits[i].t),
                                                    double(hits[i].u), double(hits[i].v), ci[i], cpu[i].prim,
                                                    double(cpu[i].t), double(cpu[i].u), double(cpu[i].v),
                                                    describe(r.tl.cmp).c_str());
                                    }
                                }
                            }
                        }
                    }
                    if (bounce < kBounces) cur = next_bounce(table, cur, ref, kSeed, uint32_t(bounce + 1));
                }
            }
            // The table so far, after every scene: a run cut short (the device tool's time limit)
            // keeps the scenes it finished. The last write, below, reports a failure to write.
            if (!csv_path.empty()) (void)write_csv(csv_path, rows, device_name, width, height, repeat);
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cwbvh_gpu_check: error: %s\n", e.what());
        if (!csv_path.empty()) (void)write_csv(csv_path, rows, device_name, width, height, repeat);  // what ran
        return 2;
    }

    if (!csv_path.empty() && !write_csv(csv_path, rows, device_name, width, height, repeat)) {
        std::fprintf(stderr, "cwbvh_gpu_check: error: %s: cannot write the CSV\n", csv_path.c_str());
        return 2;
    }
    const bool any_two_level = std::any_of(scenes.begin(), scenes.end(), [](const Scene& s) { return bool(s.two); });
    if (!csv_path.empty() && any_two_level &&
        !write_two_level_csv(two_level_csv_path(csv_path), rows, device_name, width, height, repeat)) {
        std::fprintf(stderr, "cwbvh_gpu_check: error: %s: cannot write the CSV\n",
                     two_level_csv_path(csv_path).c_str());
        return 2;
    }
    if (!cut.empty())
        std::printf("DEADLINE: stopped before %s: the tables below cover the views that ran\n", cut.c_str());
    if (!have_gpu) {
        print_two_level_table(rows);
        print_two_level_summary(rows);  // the hit comparison (no speeds without a GPU)
        print_scene_table(scenes);  // the compile side (no GAS columns without a GPU)
        std::printf("CPU-only run done (%s)%s%s\n", why.empty() ? "--cpu-only" : why.c_str(),
                    failed ? ": CPU closest/any-hit disagreement" : "", cut.empty() ? "" : " (partial: deadline)");
        return failed ? 1 : !cut.empty() ? 4 : 0;
    }
    print_table(rows);
    print_two_level_table(rows);
    print_scene_table(scenes);
    print_summary(rows);
    print_two_level_summary(rows);
    print_inline_summary(rows);
    print_postpone_summary(rows);
    std::printf("%s\n", failed ? "RESULT: FAIL" : !cut.empty() ? "RESULT: PARTIAL" : "RESULT: PASS");
    return failed ? 1 : !cut.empty() ? 4 : 0;
}
