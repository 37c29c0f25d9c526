// The progress channel behind cwbvhc's terminal phase line (progress.h): every
// counted phase ends with done == total, the channel never changes the file,
// and on a terminal the phase line shows percentages and stops cleanly.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>
#include <vector>

#include "../result_util.h"
#include "compiler/cli_support.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/progress.h"
#include "scene_corpus.h"

namespace fs = std::filesystem;
using namespace cwbvh::compiler;

namespace {

/// A wavy 150 x 150 grid (45k triangles) crossed by long thin slivers, so that the SBVH makes
/// spatial splits (more references than triangles) and builds many parallel blocks.
fs::path write_test_mesh(const fs::path& dir) {
    std::vector<std::array<double, 3>> v;
    std::vector<std::array<int, 3>> f;
    const int n = 150;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x)
            v.push_back({double(x), double(y), 2.0 * std::sin(0.3 * x) * std::cos(0.2 * y)});
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const int a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
            f.push_back({a, b, d});
            f.push_back({a, d, c});
        }
    for (int k = 0; k < 40; ++k) {  // diagonal slivers across the whole grid
        const int base = int(v.size());
        v.push_back({0.0, double(k) * 3.0, 3.0});
        v.push_back({double(n), double(n - k * 3), 3.5});
        v.push_back({double(n), double(n - k * 3) + 0.01, 3.5});
        f.push_back({base, base + 1, base + 2});
    }
    const fs::path mesh = dir / "mesh.obj";
    cwbvh::test::write_obj(mesh, v, f);
    return mesh;
}

struct PhaseEnd {
    std::string phase;
    uint64_t done, total;
};

TEST(CompileProgress, CountedPhasesEndWithDoneEqualTotalAndTheFileIsUnchanged) {
    const auto dir = cwbvh::test::temp_dir("progress");
    const fs::path mesh = write_test_mesh(dir);
    for (const auto collapse : {cwbvh::kCollapseOptimal, cwbvh::kCollapseGreedy}) {
        for (const int threads : {1, 2}) {
            SCOPED_TRACE("collapse " + std::to_string(int(collapse)) + ", threads " + std::to_string(threads));
            CompileOptions options;
            options.inputs = {mesh.string()};
            options.threads = threads;
            options.collapse = collapse;

            options.output = (dir / "plain.cwbvh").string();
            CompileStats plain_stats;
            std::string error;
            ASSERT_TRUE(::cwbvh::test::ok(compile(options, plain_stats), error)) << error;

            Progress progress;
            std::vector<PhaseEnd> ends;
            const PhaseCallback on_phase = [&](const std::string& phase, bool done, double) {
                // Start: compile() has reset the channel before calling back.
                if (!done) EXPECT_EQ(progress.done.load(), 0u) << phase;
                else ends.push_back({phase, progress.done.load(), progress.total.load()});
            };
            options.output = (dir / "progress.cwbvh").string();
            CompileStats stats;
            ASSERT_TRUE(::cwbvh::test::ok(compile(options, stats, on_phase, &progress), error)) << error;

            ASSERT_EQ(ends.size(), 6u);
            for (const PhaseEnd& e : ends) EXPECT_EQ(e.done, e.total) << e.phase;
            auto total_of = [&](const std::string& phase) {
                for (const PhaseEnd& e : ends)
                    if (e.phase == phase) return e.total;
                ADD_FAILURE() << "no phase " << phase;
                return uint64_t(0);
            };
            EXPECT_EQ(total_of("sbvh"), stats.triangles);
            EXPECT_EQ(total_of("collapse"), stats.binary_nodes);
            EXPECT_EQ(total_of("slots"), stats.wide_nodes);
            for (const char* uncounted : {"import", "encode", "write"}) EXPECT_EQ(total_of(uncounted), 0u);
            // The SBVH's share-out must stay exact when spatial splits add references.
            EXPECT_GT(stats.references, stats.triangles) << "the test mesh should make spatial splits";
            EXPECT_GT(stats.triangles, 2u * 2048u) << "several parallel blocks (kTaskRefs)";

            EXPECT_EQ(cwbvh::test::slurp(options.output), cwbvh::test::slurp(dir / "plain.cwbvh"))
                << "the progress channel changed the file";
        }
    }
}

TEST(CompileProgress, EmbreeBuilderIsNotCounted) {
    const auto dir = cwbvh::test::temp_dir("progress_embree");
    CompileOptions options;
    options.inputs = {write_test_mesh(dir).string()};
    options.output = (dir / "e.cwbvh").string();
    options.builder = cwbvh::kBuilderEmbree;
    options.threads = 2;
    Progress progress;
    std::vector<PhaseEnd> ends;
    CompileStats stats;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(compile(options, stats,
                        [&](const std::string& phase, bool done, double) {
                            if (done) ends.push_back({phase, progress.done.load(), progress.total.load()});
                        },
                        &progress), error))
        << error;
    ASSERT_EQ(ends.size(), 6u);
    EXPECT_EQ(ends[1].phase, "embree");
    EXPECT_EQ(ends[1].total, 0u);
    for (const PhaseEnd& e : ends) EXPECT_EQ(e.done, e.total) << e.phase;
}

TEST(CompileProgress, ProgressBatchPublishesInStepsAndRetracts) {
    Progress p;
    p.reset(100);
    {
        ProgressBatch batch(&p, 10);
        for (int i = 0; i < 25; ++i) batch.add(1);
        EXPECT_EQ(p.done.load(), 20u);  // two steps published, 5 pending
        batch.retract();
        EXPECT_EQ(p.done.load(), 0u);
        batch.add(7);
    }  // destruction flushes
    EXPECT_EQ(p.done.load(), 7u);
    ProgressBatch none(nullptr, 1);
    none.add(3);  // no channel: a no-op
    progress_add(nullptr, 5);
    p.reset(3);
    EXPECT_EQ(p.done.load(), 0u);
    EXPECT_EQ(p.total.load(), 3u);
}

/// cwbvhc on a pseudo-terminal (util-linux `script`): the phase line shows rising percentages
/// in 0..100 for a phase that runs over a second, nothing follows the summary, and the file is
/// the one a --quiet run through pipes writes.
TEST(CompileProgress, TerminalPhaseLineShowsPercentages) {
#if defined(__SANITIZE_ADDRESS__)
    GTEST_SKIP() << "two single-threaded dragon compiles: run in the Release pass, not under ASan";
#endif
    if (std::system("command -v script >/dev/null 2>&1") != 0) GTEST_SKIP() << "util-linux script not installed";
    const std::string dragon = cwbvh::test::corpus_scene("dragon.glb");
    CWBVH_REQUIRE_SCENE(dragon);
    const auto dir = cwbvh::test::temp_dir("progress_tty");
    const std::string out = (dir / "tty.cwbvh").string(), quiet = (dir / "quiet.cwbvh").string();
    const fs::path captured = dir / "terminal.txt";
    // One thread: the SBVH then takes a few seconds on the 871k-triangle dragon.
    const std::string inner = cwbvh::test::shell_quote(std::string(CWBVH_BIN_DIR) + "/cwbvhc") + " " +
                              cwbvh::test::shell_quote(dragon) + " -o " + cwbvh::test::shell_quote(out) +
                              " --threads 1";
    const std::string cmd = "script -qec " + cwbvh::test::shell_quote(inner) + " /dev/null </dev/null >" +
                            cwbvh::test::shell_quote(captured.string()) + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    const std::string text = cwbvh::test::slurp(captured);

    for (const char* phase : {"import", "sbvh", "collapse", "slots", "encode", "write"})
        EXPECT_NE(text.find(std::string("\r\033[K[cwbvhc] ") + phase + " ..."), std::string::npos) << phase;
    const size_t summary = text.find("cwbvhc summary");
    ASSERT_NE(summary, std::string::npos) << text;
    EXPECT_EQ(text.find("[cwbvhc]", summary), std::string::npos) << "phase-line output after the summary";

    // Percent lines: within 0..100 and never falling within a phase.
    const std::regex percent_line("\\[cwbvhc\\] (\\S+) +(\\d+)%");
    std::string last_phase;
    int last = -1, sbvh_lines = 0;
    for (auto it = std::sregex_iterator(text.begin(), text.end(), percent_line); it != std::sregex_iterator(); ++it) {
        const std::string phase = (*it)[1];
        const int pct = std::stoi((*it)[2]);
        EXPECT_GE(pct, 0);
        EXPECT_LE(pct, 100);
        if (phase == last_phase) {
            EXPECT_GT(pct, last) << phase;
        }
        last_phase = phase;
        last = pct;
        sbvh_lines += phase == "sbvh";
    }
    std::smatch seconds;
    ASSERT_TRUE(std::regex_search(text, seconds, std::regex("seconds sbvh +([0-9.]+)"))) << text;
    if (std::stod(seconds[1]) > 1.5) {
        EXPECT_GT(sbvh_lines, 0) << "no percentage in a " << seconds[1] << " s phase";
    } else {
        std::printf("sbvh took %s s: too fast to check for a percentage\n", std::string(seconds[1]).c_str());
    }

    const auto r = cwbvh::test::run_tool("cwbvhc", {dragon, "-o", quiet, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty());
    EXPECT_EQ(cwbvh::test::slurp(out), cwbvh::test::slurp(quiet));
}

}  // namespace
