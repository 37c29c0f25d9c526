// cwbvh_gpu_check's two-level path (tools/gpu_check), as far as it runs without a GPU:
//  - hit_compare.h's compare_with_flattened (the two-level file's hits against the
//    flattened file's: hit/miss, 1e-5 relative t, PMAP source or tie; edge cases and
//    diffuse rounding counted apart) and compare_query (the two-level kernel and the inline
//    query against their CPU references: closest hit bit for bit up to equal-t ties and
//    4 ulps, any hit by hit/miss and no nearer than the closest), each with its bad case;
//  - the tool itself with --cpu-only on dense_dragons compiled both ways by cwbvhc
//    (ray generation, trace_two_level_cpu, the comparison, the two-level table and CSV,
//    the scene table's instanced columns), a flattened file of another scene under the
//    same key (the comparison must report disagreements), and the usage errors;
//  - without --cpu-only: "SKIPPED" with no device (as before), and with one the
//    two-level kernel on 32x32 rays, bit for bit with trace_two_level_cpu.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "hit_compare.h"
#include "scene_corpus.h"

namespace cwbvh::test {
namespace {

Hit hit(float t, uint32_t prim, float u = 0.25f, float v = 0.25f) { return Hit{t, u, v, prim}; }
Hit miss() { return Hit{std::numeric_limits<float>::infinity(), 0, 0, kMissPrim}; }

/// Same source when the prims are equal modulo 1000 (two files number them differently).
bool same_mod(uint32_t a, uint32_t b) { return a % 1000 == b % 1000; }

FlatCompare cmp(const std::vector<Hit>& two, const std::vector<Hit>& flat, bool any = false, double slack = 0,
                double cos = 1.0) {
    return compare_with_flattened(two, flat, any, slack, same_mod, [&](size_t, uint32_t) { return cos; });
}

TEST(GpuCheckTwoLevel, EqualHitsAgree) {
    const std::vector<Hit> a = {hit(2.0f, 1005), miss(), hit(7.5f, 1)};
    const std::vector<Hit> b = {hit(2.0f, 5), miss(), hit(7.5f, 2001)};
    const FlatCompare c = cmp(a, b);
    EXPECT_EQ(c.rays, 3u);
    EXPECT_EQ(c.hits, 2u);
    EXPECT_EQ(c.disagreeing, 0u);
    EXPECT_EQ(c.ties, 0u);
    EXPECT_EQ(c.first_bad, -1);
}

TEST(GpuCheckTwoLevel, HitVersusMissAwayFromAnEdgeDisagrees) {
    const FlatCompare c = cmp({miss(), hit(3.0f, 1)}, {miss(), miss()});
    EXPECT_EQ(c.hit_vs_miss, 1u);
    EXPECT_EQ(c.edge, 0u);
    EXPECT_EQ(c.disagreeing, 1u);
    EXPECT_EQ(c.first_bad, 1);
    // The other way round too (the flattened file hits).
    EXPECT_EQ(cmp({miss()}, {hit(3.0f, 1)}).hit_vs_miss, 1u);
}

TEST(GpuCheckTwoLevel, HitVersusMissAtAnEdgeIsCountedApart) {
    // min(u, v, 1-u-v) = 1e-5 exactly is an edge; just above it is not.
    const FlatCompare at = cmp({hit(3.0f, 1, 1e-5f, 0.5f)}, {miss()});
    EXPECT_EQ(at.edge, 1u);
    EXPECT_EQ(at.disagreeing, 0u);
    const FlatCompare off = cmp({hit(3.0f, 1, 2e-5f, 0.5f)}, {miss()});
    EXPECT_EQ(off.edge, 0u);
    EXPECT_EQ(off.hit_vs_miss, 1u);
    // The third barycentric: u + v = 1.
    EXPECT_EQ(cmp({miss()}, {hit(3.0f, 1, 0.5f, 0.5f)}).edge, 1u);
}

TEST(GpuCheckTwoLevel, TRelativeBound) {
    // 1e-5 relative is close (worst_rel records it); 2e-5 is not.
    const FlatCompare in = cmp({hit(float(1.0 + 0.9e-5), 1)}, {hit(1.0f, 1)});
    EXPECT_EQ(in.disagreeing, 0u);
    EXPECT_GT(in.worst_rel, 0.8e-5);
    EXPECT_LE(in.worst_rel, 1e-5);
    const FlatCompare out = cmp({hit(float(1.0 + 2e-5), 1)}, {hit(1.0f, 1)});
    EXPECT_EQ(out.t_far, 1u);
    EXPECT_EQ(out.source, 0u);  // same source: only t disagrees
    EXPECT_EQ(out.disagreeing, 1u);
}

TEST(GpuCheckTwoLevel, TWithinTheRoundingAlongTheNormal) {
    // gap 1e-3 at t = 1: beyond 1e-5 relative. Along a normal at cos 0.01 the gap is
    // 1e-5, within a slack of 2e-5 (accepted, counted); at cos 1 it is 1e-3 (not).
    const std::vector<Hit> a = {hit(1.001f, 1)}, b = {hit(1.0f, 1)};
    const FlatCompare grazing = cmp(a, b, false, 2e-5, 0.01);
    EXPECT_EQ(grazing.t_rounding, 1u);
    EXPECT_EQ(grazing.disagreeing, 0u);
    const FlatCompare head_on = cmp(a, b, false, 2e-5, 1.0);
    EXPECT_EQ(head_on.t_far, 1u);
    EXPECT_EQ(head_on.disagreeing, 1u);
    // An unknown normal (< 0) never widens the bound.
    EXPECT_EQ(cmp(a, b, false, 1.0, -1.0).t_far, 1u);
    // The slack of a scene of extent E: 16 u E.
    EXPECT_DOUBLE_EQ(flat_rounding_slack(1000.0), 16.0 * 1000.0 / 16777216.0);
}

TEST(GpuCheckTwoLevel, AnotherSourceIsATieOnlyAtACloseT) {
    const FlatCompare tie = cmp({hit(5.0f, 7)}, {hit(5.0f, 8)});
    EXPECT_EQ(tie.ties, 1u);
    EXPECT_EQ(tie.disagreeing, 0u);
    // Another source at a far t, neither hit at an edge: t and source both count, one ray.
    const FlatCompare far = cmp({hit(5.0f, 7)}, {hit(4.0f, 8)});
    EXPECT_EQ(far.t_far, 1u);
    EXPECT_EQ(far.source, 1u);
    EXPECT_EQ(far.disagreeing, 1u);
}

TEST(GpuCheckTwoLevel, AFartherHitBehindAnEdgeHitIsAnEdgeCase) {
    // The nearer hit (flattened, t 4) lies on an edge (v = 0): the two-level file's
    // rounding missed that triangle there and hit one behind it.
    const FlatCompare c = cmp({hit(5.0f, 7)}, {hit(4.0f, 8, 0.5f, 0.0f)});
    EXPECT_EQ(c.edge, 1u);
    EXPECT_EQ(c.disagreeing, 0u);
    // The FARTHER hit at an edge does not excuse it.
    const FlatCompare d = cmp({hit(5.0f, 7, 0.5f, 0.0f)}, {hit(4.0f, 8)});
    EXPECT_EQ(d.edge, 0u);
    EXPECT_EQ(d.disagreeing, 1u);
    // Nor does an edge when the source is the same (then t alone disagrees).
    const FlatCompare e = cmp({hit(5.0f, 8)}, {hit(4.0f, 8, 0.5f, 0.0f)});
    EXPECT_EQ(e.t_far, 1u);
    EXPECT_EQ(e.disagreeing, 1u);
}

TEST(GpuCheckTwoLevel, AnyHitComparesHitOrMissOnly) {
    const FlatCompare c = cmp({hit(5.0f, 7), miss()}, {hit(1.0f, 8), hit(2.0f, 9)}, true);
    EXPECT_EQ(c.hits, 1u);
    EXPECT_EQ(c.t_far + c.source + c.ties, 0u);
    EXPECT_EQ(c.hit_vs_miss, 1u);
    EXPECT_EQ(c.first_bad, 1);
}

TEST(GpuCheckTwoLevel, SumsKeepTheFirstDisagreementsRayIndex) {
    FlatCompare total = cmp({miss(), miss()}, {miss(), miss()});
    total += cmp({miss(), hit(1.0f, 1)}, {miss(), miss()});
    EXPECT_EQ(total.rays, 4u);
    EXPECT_EQ(total.first_bad, 3);
    total += cmp({hit(1.0f, 1)}, {miss()});
    EXPECT_EQ(total.first_bad, 3);
    EXPECT_EQ(total.disagreeing, 2u);
}

TEST(GpuCheckTwoLevel, QueriesAgainstTheCpuReference) {
    const std::vector<Hit> ref = {hit(1.0f, 1), miss(), hit(2.0f, 3)};
    const std::vector<uint32_t> ri = {4, kInvalidIndex, 9};
    QueryCompare c = compare_query(ref, ri, ref, ri, false, ref);
    EXPECT_EQ(c.mismatches, 0u);
    EXPECT_EQ(c.not_bitwise, 0u);
    EXPECT_EQ(c.first_bad, -1);
    // One ulp of t on the same triangle: not bit for bit, accepted (the double path).
    std::vector<Hit> h = ref;
    h[2].t = std::nextafter(2.0f, 3.0f);
    c = compare_query(h, ri, ref, ri, false, ref);
    EXPECT_EQ(c.mismatches, 0u);
    EXPECT_EQ(c.not_bitwise, 1u);
    EXPECT_EQ(c.near, 1u);
    // Five ulps: a mismatch.
    h[2].t = 2.0f;
    for (int i = 0; i < 5; ++i) h[2].t = std::nextafter(h[2].t, 3.0f);
    c = compare_query(h, ri, ref, ri, false, ref);
    EXPECT_EQ(c.mismatches, 1u);
    EXPECT_EQ(c.first_bad, 2);
    // Another instance of the same prim at the same t: an equal-t tie (which of two
    // triangles at one distance wins depends on the order they are tested in).
    std::vector<uint32_t> hi = ri;
    hi[0] = 5;
    c = compare_query(ref, hi, ref, ri, false, ref);
    EXPECT_EQ(c.mismatches, 0u);
    EXPECT_EQ(c.ties, 1u);
    // Another prim at the same t: a tie too.
    h = ref;
    h[0].prim = 2;
    h[0].u = 0.5f;
    c = compare_query(h, ri, ref, ri, false, ref);
    EXPECT_EQ(c.ties, 1u);
    EXPECT_EQ(c.mismatches, 0u);
    // Hit against miss: a mismatch, either way.
    h = ref;
    h[1] = hit(3.0f, 7);
    c = compare_query(h, ri, ref, ri, false, ref);
    EXPECT_EQ(c.mismatches, 1u);
    h = ref;
    h[0] = miss();
    c = compare_query(h, ri, ref, ri, true, ref);
    EXPECT_EQ(c.mismatches, 1u);
    // A miss record whose bits differ (u of a miss): a mismatch.
    h = ref;
    h[1].u = 0.25f;
    c = compare_query(h, ri, ref, ri, false, ref);
    EXPECT_EQ(c.mismatches, 1u);
    EXPECT_EQ(c.first_bad, 1);
}

TEST(GpuCheckTwoLevel, AnyHitAcceptsAnotherHitNoNearerThanTheClosest) {
    const std::vector<Hit> closest = {hit(1.0f, 1), hit(2.0f, 3)};
    const std::vector<Hit> ref_any = {hit(4.0f, 2), hit(2.0f, 3)};
    const std::vector<uint32_t> ri = {0, 0};
    // The kernel found other hits than the reference's any-hit ones, both no nearer than
    // the closest hit: accepted.
    std::vector<Hit> h = {hit(1.0f, 1), hit(5.0f, 6)};
    QueryCompare c = compare_query(h, ri, ref_any, ri, true, closest);
    EXPECT_EQ(c.mismatches, 0u);
    EXPECT_EQ(c.not_bitwise, 2u);
    EXPECT_EQ(c.ties, 0u);
    // A hit nearer than the closest one cannot be a hit: a mismatch.
    h[1] = hit(1.5f, 6);
    c = compare_query(h, ri, ref_any, ri, true, closest);
    EXPECT_EQ(c.mismatches, 1u);
    EXPECT_EQ(c.first_bad, 1);
    // ... unless within the ulp bound of it.
    h[1] = hit(std::nextafter(2.0f, 0.0f), 6);
    c = compare_query(h, ri, ref_any, ri, true, closest);
    EXPECT_EQ(c.mismatches, 0u);
}

// ---- the tool, --cpu-only ------------------------------------------------

namespace fs = std::filesystem;

struct ToolRun {
    int rc = -1;
    std::string out;
};

ToolRun run_tool(const std::string& args) {
    static int n = 0;
    const fs::path log = fs::path(::testing::TempDir()) /
                         ("gpu_check_two_level_" + std::to_string(::getpid()) + "_" + std::to_string(n++) + ".log");
    const std::string cmd = "\"" + std::string(CWBVH_BIN_DIR) + "/cwbvh_gpu_check\" " + args + " > \"" +
                            log.string() + "\" 2>&1";
    ToolRun r;
    const int st = std::system(cmd.c_str());
    r.rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
    std::ifstream f(log);
    std::stringstream ss;
    ss << f.rdbuf();
    r.out = ss.str();
    fs::remove(log);
    return r;
}

class GpuCheckTool : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        dir_ = fs::path(::testing::TempDir()) / ("gpu_check_two_level_" + std::to_string(::getpid()));
        fs::create_directories(dir_ / "flat");
        fs::create_directories(dir_ / "instanced");
        fs::create_directories(dir_ / "wrong");
    }
    static void TearDownTestSuite() {
        std::error_code ec;
        fs::remove_all(dir_, ec);
    }
    void SetUp() override {
        if (!fs::exists(fs::path(CWBVH_BIN_DIR) / "cwbvh_gpu_check") || !fs::exists(fs::path(CWBVH_BIN_DIR) / "cwbvhc"))
            GTEST_SKIP() << "cwbvh_gpu_check or cwbvhc not built";
    }
    /// cwbvhc SCENE FLAGS -o OUT, once per suite.
    static std::string compile(const std::string& scene, const std::string& flags, const fs::path& out) {
        if (!fs::exists(out)) {
            const std::string cmd = "\"" + std::string(CWBVH_BIN_DIR) + "/cwbvhc\" \"" + corpus_scene(scene) + "\" " +
                                    flags + " --threads 2 --quiet -o \"" + out.string() + "\"";
            EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
        }
        return out.string();
    }
    static fs::path dir_;
};
fs::path GpuCheckTool::dir_;

size_t count_lines(const std::string& path) {
    std::ifstream f(path);
    size_t n = 0;
    for (std::string line; std::getline(f, line);) ++n;
    return n;
}

TEST_F(GpuCheckTool, ComparesTheInstancedFileWithTheFlattenedOnTheSameRays) {
    CWBVH_REQUIRE_SCENE(corpus_scene("dense_dragons.glb"));
    const std::string flat = compile("dense_dragons.glb", "--flatten", dir_ / "flat" / "dense_dragons.cwbvh");
    const std::string two = compile("dense_dragons.glb", "", dir_ / "instanced" / "dense_dragons.cwbvh");
    const fs::path times = dir_ / "times.txt";
    std::ofstream(times) << "dense_dragons 4.5\ninstanced:dense_dragons 0.25\n";
    const fs::path csv = dir_ / "table.csv";
    // The instanced file first: the pairing does not depend on the order.
    const ToolRun r = run_tool("--cpu-only --width 40 --height 40 --compile-times \"" + times.string() + "\" --csv \"" +
                      csv.string() + "\" \"" + two + "\" \"" + flat + "\"");
    ASSERT_EQ(r.rc, 0) << r.out;
    // Every view and ray set: the two-level CPU reference and a comparison line each.
    EXPECT_NE(r.out.find("two-level      "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("2L closest vs flattened (CPU): 0 disagreeing"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("Two-level (instanced file) vs flattened file, same rays:"), std::string::npos);
    EXPECT_NE(r.out.find("two-level vs flattened hits (CPU references), all rays and queries: 0 disagreeing"),
              std::string::npos)
        << r.out;
    // The scene table: the instanced file's size and compile time beside the flattened ones.
    EXPECT_NE(r.out.find("2L cmp s"), std::string::npos);
    EXPECT_NE(r.out.find("dense_dragons two-level: 1 meshes placed 200 times, 11102 distinct / 2220400 instanced"),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("compile 0.25 s (the flattened file's 4.50 s: 18.0x faster)"), std::string::npos) << r.out;
    // The two-level CSV: header + 2 views x 5 ray sets x 2 queries (the catalog has two
    // dense_dragons views), beside the single-level table.
    const std::string csv2 = (dir_ / "table_two_level.csv").string();
    ASSERT_TRUE(fs::exists(csv2));
    EXPECT_EQ(count_lines(csv2), 1u + 2 * 5 * 2);
    EXPECT_EQ(count_lines(csv.string()), 1u + 2 * 5 * 2);
}

TEST_F(GpuCheckTool, WithoutCpuOnlySkipsWithoutADeviceAndPassesWithOne) {
    // No device: the existing "SKIPPED" (exit 0) before any scene is read. A device:
    // the two-level kernel on 32x32 rays, bit for bit with trace_two_level_cpu.
    CWBVH_REQUIRE_SCENE(corpus_scene("dense_dragons.glb"));
    const std::string flat = compile("dense_dragons.glb", "--flatten", dir_ / "flat" / "dense_dragons.cwbvh");
    const std::string two = compile("dense_dragons.glb", "", dir_ / "instanced" / "dense_dragons.cwbvh");
    const ToolRun r = run_tool("--width 32 --height 32 --repeat 1 --no-optix \"" + flat + "\" \"" + two + "\"");
    ASSERT_EQ(r.rc, 0) << r.out;
    if (r.out.rfind("SKIPPED: no CUDA device", 0) == 0) return;
    EXPECT_NE(r.out.find("RESULT: PASS"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("2L closest"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("two-level kernel vs trace_two_level_cpu: 0 rays not bit for bit"), std::string::npos)
        << r.out;
}

TEST_F(GpuCheckTool, AnotherScenesFlattenedFileDisagrees) {
    // The bad case of the comparison: the same key, another scene's geometry (the
    // dragon_res4 that dense_dragons places, once, at the origin: not where the 200
    // copies stand). The tool reports the disagreements (not a failure: exit 0).
    CWBVH_REQUIRE_SCENE(corpus_scene("dense_dragons.glb"));
    CWBVH_REQUIRE_SCENE(corpus_scene("dragon_res4.glb"));
    const std::string two = compile("dense_dragons.glb", "", dir_ / "instanced" / "dense_dragons.cwbvh");
    const std::string wrong = compile("dragon_res4.glb", "--flatten", dir_ / "wrong" / "dense_dragons.cwbvh");
    const ToolRun r = run_tool("--cpu-only --width 32 --height 32 \"" + wrong + "\" \"" + two + "\"");
    ASSERT_EQ(r.rc, 0) << r.out;
    const std::string key = "two-level vs flattened hits (CPU references), all rays and queries: ";
    const size_t at = r.out.find(key);
    ASSERT_NE(at, std::string::npos) << r.out;
    EXPECT_GT(std::strtoull(r.out.c_str() + at + key.size(), nullptr, 10), 100u) << r.out.substr(at, 200);
    EXPECT_NE(r.out.find("first disagreement: ray"), std::string::npos);
}

TEST_F(GpuCheckTool, TwoLevelFileNeedsItsFlattenedPartner) {
    CWBVH_REQUIRE_SCENE(corpus_scene("dense_dragons.glb"));
    const std::string flat = compile("dense_dragons.glb", "--flatten", dir_ / "flat" / "dense_dragons.cwbvh");
    const std::string two = compile("dense_dragons.glb", "", dir_ / "instanced" / "dense_dragons.cwbvh");
    ToolRun r = run_tool("--cpu-only \"" + two + "\"");
    EXPECT_EQ(r.rc, 2);
    EXPECT_NE(r.out.find("a two-level file needs the flattened file of the same scene beside it"), std::string::npos)
        << r.out;
    // Two two-level files for one scene: which one to measure is ambiguous.
    const fs::path copy = dir_ / "wrong" / "instanced_copy";
    fs::create_directories(copy);
    fs::copy_file(two, copy / "dense_dragons.cwbvh", fs::copy_options::overwrite_existing);
    r = run_tool("--cpu-only \"" + flat + "\" \"" + two + "\" \"" + (copy / "dense_dragons.cwbvh").string() + "\"");
    EXPECT_EQ(r.rc, 2);
    EXPECT_NE(r.out.find("a second two-level file for scene dense_dragons"), std::string::npos) << r.out;
    // The two-level CSV (PATH's stem + _two_level.csv) never overwrites an input either.
    const fs::path input = dir_ / "wrong" / "dense_two_level.csv";
    std::ofstream(input) << "not a table\n";
    r = run_tool("--cpu-only --csv \"" + (dir_ / "wrong" / "dense.csv").string() + "\" \"" + flat + "\" \"" +
            input.string() + "\"");
    EXPECT_EQ(r.rc, 2);
    EXPECT_NE(r.out.find("refusing to overwrite it"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace cwbvh::test
