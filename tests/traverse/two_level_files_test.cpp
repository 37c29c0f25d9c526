// Two-level files as cwbvhc writes them (format 1.2) against the same scene
// compiled with --flatten, on the catalog views of the instanced corpus scenes
// (kicad_board: 259 meshes placed 1009 times; dense_dragons: one mesh placed 200
// times): primary rays and one diffuse bounce (generated on the flattened file, so
// both files answer the same rays). Issue 19's criterion: hit/miss equal; t within
// 1e-5 relative; the same source primitive (PMAP: input, mesh, primitive, triangle)
// or an equal-t tie (dense_dragons' dragon has coincident triangles: ~1% of its
// primary hits are exact ties). Also: the hit file written by `cwbvh trace` for a two-level
// file carries the instances (version 1.1).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/view_catalog.h"
#include "cwbvh/loader/loader.h"
#include "scene_corpus.h"

namespace cwbvh::test {
namespace {

namespace fs = std::filesystem;

/// This run's scratch folder (per process: never a file an older cwbvhc wrote).
const fs::path& scratch() {
    static const fs::path dir = [] {
        fs::path d = fs::path(::testing::TempDir()) / ("cwbvh_two_level_files_" + std::to_string(::getpid()));
        fs::create_directories(d);
        return d;
    }();
    return dir;
}

/// Removes the scratch folder (~370 MB of compiled scenes) when the program ends.
class ScratchCleanup : public ::testing::Environment {
public:
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(fs::path(::testing::TempDir()) / ("cwbvh_two_level_files_" + std::to_string(::getpid())), ec);
    }
};
const bool kScratchCleanupRegistered = (::testing::AddGlobalTestEnvironment(new ScratchCleanup), true);

/// Compiles `scene` with cwbvhc (extra flags) into the scratch folder, once per run.
std::string compile(const std::string& scene, const std::string& flags, const std::string& out_name) {
    const fs::path out = scratch() / out_name;
    if (fs::exists(out)) return out.string();
    const fs::path cwbvhc = fs::path(CWBVH_BIN_DIR) / "cwbvhc";
    const std::string cmd = "\"" + cwbvhc.string() + "\" \"" + corpus_scene(scene) + "\" " + flags + " -o \"" +
                            out.string() + "\" > /dev/null";
    EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
    return out.string();
}

TwoLevelScene view(const File& f) {
    return TwoLevelScene{f.top_nodes().data(), uint32_t(f.top_nodes().size()), f.instances().data(),
                         uint32_t(f.instances().size()),  f.meshes().data(), uint32_t(f.meshes().size()),
                         f.nodes().data(),     uint32_t(f.nodes().size()),     f.triangles().data(),
                         uint32_t(f.triangles().size())};
}

struct Tally {
    size_t rays = 0, hits = 0, hit_mismatch = 0, edge = 0, t_mismatch = 0, t_rounding = 0, source_mismatch = 0, ties = 0;
    double worst_t = 0;
};

constexpr double kU = 5.9604644775390625e-08;  // 2^-24

/// Largest |coordinate| of the scene bounds: the size of the roundings of world
/// coordinates (the flattened file's vertices, the two-level ray's object-space
/// origin) is u times this.
double extent(const File& f) {
    double e = 0;
    for (int a = 0; a < 3; ++a)
        e = std::max({e, std::fabs(double(f.bounds()->lo[a])), std::fabs(double(f.bounds()->hi[a]))});
    return e;
}

/// The criterion: hit/miss equal; t within 1e-5 relative, or else (a ray that starts
/// near a surface, like a diffuse bounce ray, or meets one at a grazing angle) the gap
/// measured along the surface normal, |dt| |d| |cos|, within 16 u of the scene's
/// extent: both files round world coordinates of that size, which is all the
/// agreement there can be (counted as t_rounding, reported); the same source
/// primitive, or a tie: another triangle met at a t that agrees as closely.
void compare(const File& two, const File& flat, const PrimTable& flat_tris, const std::vector<Ray>& rays,
             const std::vector<Hit>& a, const std::vector<uint32_t>& inst, const std::vector<Hit>& b, Tally& t) {
    const double slack = 16 * kU * extent(flat);
    for (size_t i = 0; i < a.size(); ++i) {
        ++t.rays;
        const bool ha = a[i].prim != kMissPrim, hb = b[i].prim != kMissPrim;
        EXPECT_EQ(ha, inst[i] != kInvalidIndex);
        if (ha != hb) {
            // The side that hit met the triangle within 1e-5 (barycentric) of an edge:
            // the two files' roundings (vertices vs object-space ray) may each decide
            // such a ray either way when the edge is a mesh boundary. Counted apart.
            const Hit& h = ha ? a[i] : b[i];
            const double m = std::min({double(h.u), double(h.v), 1.0 - double(h.u) - double(h.v)});
            if (m <= 1e-5) ++t.edge;
            else ++t.hit_mismatch;
            continue;
        }
        if (!ha) continue;
        ++t.hits;
        const double gap = std::fabs(double(a[i].t) - b[i].t);
        const double rel = gap / std::fabs(double(b[i].t));
        bool close = rel <= 1e-5;
        if (!close) {
            const TriangleRecord* tri = flat_tris.find(b[i].prim);
            float n[3] = {0, 0, 0};
            ASSERT_TRUE(tri && geometric_normal(*tri, n));
            const double c = std::fabs(double(n[0]) * rays[i].dir[0] + double(n[1]) * rays[i].dir[1] +
                                       double(n[2]) * rays[i].dir[2]);
            close = gap * c <= slack;
            if (close) ++t.t_rounding;
            else ++t.t_mismatch;
        }
        if (rel <= 1e-5) t.worst_t = std::max(t.worst_t, rel);
        const auto sa = two.source_of(a[i].prim), sb = flat.source_of(b[i].prim);
        ASSERT_TRUE(sa && sb);
        if (sa->input != sb->input || sa->mesh != sb->mesh || sa->primitive != sb->primitive ||
            sa->triangle != sb->triangle) {
            if (close) ++t.ties;
            else ++t.source_mismatch;
        }
    }
}

void check_scene(const std::string& scene_file, const std::string& key) {
    CWBVH_REQUIRE_SCENE(corpus_scene(scene_file));
    const std::string two_path = compile(scene_file, "", key + ".cwbvh");
    const std::string flat_path = compile(scene_file, "--flatten", key + "_flat.cwbvh");
    auto two = File::open(two_path);
    auto flat = File::open(flat_path);
    ASSERT_TRUE(two.ok()) << two.error().message;
    ASSERT_TRUE(flat.ok()) << flat.error().message;
    ASSERT_TRUE(two->is_two_level()) << two_path << ": cwbvhc kept no instancing";
    ASSERT_FALSE(flat->is_two_level());
    ViewCatalog catalog;
    ASSERT_TRUE(ViewCatalog::load(std::string(CWBVH_SOURCE_DIR) + "/views/catalog.txt", catalog).ok());
    const std::vector<View> views = catalog.views_of(key);
    ASSERT_FALSE(views.empty());
    const TwoLevelScene s = view(*two);
    const auto fn = flat->nodes();
    const auto ft = flat->triangles();
    const PrimTable flat_tris(ft.data(), ft.size());
    for (const View& v : views) {
        const std::vector<Ray> primary = camera_rays(v.camera, 160, 160);
        const DiffuseRays diffuse = diffuse_rays(fn.data(), fn.size(), ft.data(), ft.size(), primary, 1, 1, 0);
        for (int kind = 0; kind < 2; ++kind) {
            const std::vector<Ray>& rays = kind == 0 ? primary : diffuse.rays;
            for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
                CpuTraceOptions o;
                o.mode = mode;
                std::vector<Hit> a(rays.size()), b(rays.size());
                std::vector<uint32_t> inst(rays.size());
                const CpuTraceStats sa = trace_two_level_cpu(s, rays.data(), a.data(), inst.data(), rays.size(), o);
                trace_cwbvh_cpu(fn.data(), fn.size(), ft.data(), ft.size(), rays.data(), b.data(), rays.size(), o);
                EXPECT_EQ(sa.stack_overflows + sa.bad_indices, 0u);
                Tally t;
                if (mode == HitMode::kClosest) {
                    compare(*two, *flat, flat_tris, rays, a, inst, b, t);
                } else {
                    for (size_t i = 0; i < rays.size(); ++i) {
                        ++t.rays;
                        t.hits += a[i].prim != kMissPrim;
                        // Any hit: each side's answer is some hit; hit exactly when the
                        // closest query hits (its edge cases counted as above).
                        t.hit_mismatch += (a[i].prim != kMissPrim) != (b[i].prim != kMissPrim);
                    }
                }
                std::printf("%-13s %-5s %-7s %-7s rays %6zu hits %6zu  hit/miss %zu (edge %zu)  t %zu (1e-5 rel: worst %.2g; "
                            "within rounding %zu)  source %zu  ties %zu\n",
                            key.c_str(), v.name.c_str(), kind == 0 ? "primary" : "diffuse",
                            mode == HitMode::kAny ? "any" : "closest", t.rays, t.hits, t.hit_mismatch, t.edge, t.t_mismatch,
                            t.worst_t, t.t_rounding, t.source_mismatch, t.ties);
                EXPECT_GT(t.hits, t.rays / 10) << key << " " << v.name;
                EXPECT_EQ(t.hit_mismatch, 0u) << key << " " << v.name;
                EXPECT_LE(t.edge * 10000, t.rays) << key << " " << v.name;
                EXPECT_EQ(t.t_mismatch, 0u) << key << " " << v.name;
                EXPECT_EQ(t.source_mismatch, 0u) << key << " " << v.name;
                if (kind == 0) {
                    EXPECT_EQ(t.t_rounding, 0u) << key << " " << v.name << ": primary rays, 1e-5 relative";
                }
            }
        }
    }
}

TEST(TwoLevelFiles, DenseDragonsMatchesFlattened) { check_scene("dense_dragons.glb", "dense_dragons"); }

TEST(TwoLevelFiles, KicadBoardMatchesFlattened) { check_scene("kicad_board.glb", "kicad_board"); }

TEST(TwoLevelFiles, TraceWritesInstanceHitFile) {
    CWBVH_REQUIRE_SCENE(corpus_scene("dense_dragons.glb"));
    const std::string two_path = compile("dense_dragons.glb", "", "dense_dragons.cwbvh");
    const fs::path dir = scratch();
    const std::string rays = (dir / "dd.rays").string(), hits = (dir / "dd.hits").string();
    const std::string cwbvh = (fs::path(CWBVH_BIN_DIR) / "cwbvh").string();
    const std::string q = "\"";
    ASSERT_EQ(std::system((q + cwbvh + q + " rays " + q + two_path + q +
                           " --scene dense_dragons --primary --width 64 --height 64 -o " + q + rays + q + " > /dev/null")
                              .c_str()),
              0);
    ASSERT_EQ(std::system((q + cwbvh + q + " trace " + q + two_path + q + " --rays " + q + rays + q + " --hits " + q +
                           hits + q + " > /dev/null")
                              .c_str()),
              0);
    std::vector<Hit> h;
    std::vector<uint32_t> inst;
    uint32_t flags = 0;
    ASSERT_TRUE(read_hit_file(hits, h, inst, flags).ok());
    ASSERT_EQ(h.size(), 64u * 64u);
    ASSERT_EQ(inst.size(), h.size());
    auto f = File::open(two_path);
    ASSERT_TRUE(f.ok());
    size_t n = 0;
    for (size_t i = 0; i < h.size(); ++i) {
        EXPECT_EQ(h[i].prim == kMissPrim, inst[i] == kInvalidIndex);
        if (inst[i] == kInvalidIndex) continue;
        ++n;
        ASSERT_LT(inst[i], f->instances().size());
        const MeshRecord& m = f->meshes()[f->instances()[inst[i]].mesh];
        EXPECT_GE(h[i].prim, m.prim_first);
        EXPECT_LT(h[i].prim, m.prim_first + m.prim_count);
    }
    EXPECT_GT(n, h.size() / 10);
    // The 16-byte reader refuses the 1.1 file by name.
    EXPECT_FALSE(read_hit_file(hits, h, flags).ok());
}

}  // namespace
}  // namespace cwbvh::test
