// The progress channel behind cwbvhc's terminal phase line (progress.h): every
// counted phase ends with done == total, the channel never changes the file,
// and on a terminal the phase line shows percentages and stops cleanly.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <regex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "../result_util.h"
#include "compiler/cli_support.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/phase_line.h"
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

/// The names in `dir` (a cancelled compile must leave no temporary file behind).
std::vector<std::string> listing(const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

TEST(CompileProgress, ACallbackThatThrowsCancelsTheCompileBeforeTheWrite) {
    // compile.h: a throw from the PhaseCallback leaves compile() at once; before the write's end
    // nothing is written and a file already at the output path keeps its bytes. Checked at every
    // phase start and end of a compile, with and without such a file.
    const auto dir = cwbvh::test::temp_dir("progress_cancel");
    std::vector<std::array<double, 3>> v;
    std::vector<std::array<int, 3>> f;
    for (int y = 0; y <= 20; ++y)
        for (int x = 0; x <= 20; ++x) v.push_back({double(x), double(y), std::sin(0.5 * x)});
    for (int y = 0; y < 20; ++y)
        for (int x = 0; x < 20; ++x) {
            const int a = y * 21 + x;
            f.push_back({a, a + 1, a + 22});
            f.push_back({a, a + 22, a + 21});
        }
    cwbvh::test::write_obj(dir / "grid.obj", v, f);
    CompileOptions options;
    options.inputs = {(dir / "grid.obj").string()};
    options.output = (dir / "full.cwbvh").string();
    options.threads = 2;
    std::vector<std::pair<std::string, bool>> calls;
    CompileStats full;
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(compile(options, full,
                                          [&](const std::string& phase, bool done, double) {
                                              calls.emplace_back(phase, done);
                                          }),
                                  error))
        << error;
    ASSERT_EQ(calls.back(), std::make_pair(std::string("write"), true));

    struct Stop {};
    const fs::path out = dir / "cancelled.cwbvh";
    const std::string old = "the file that was there before";
    for (size_t at = 0; at + 1 < calls.size(); ++at) {
        for (const bool existing : {false, true}) {
            SCOPED_TRACE(calls[at].first + (calls[at].second ? " end" : " start") +
                         (existing ? ", over an existing file" : ""));
            fs::remove(out);
            if (existing) std::ofstream(out, std::ios::binary) << old;
            const std::vector<std::string> before = listing(dir);
            options.output = out.string();
            size_t n = 0;
            CompileStats stats;
            EXPECT_THROW(compile(options, stats,
                                 [&](const std::string&, bool, double) {
                                     if (n++ == at) throw Stop{};
                                 }),
                         Stop);
            EXPECT_EQ(n, at + 1) << "the compile went on after the callback threw";
            if (existing) EXPECT_EQ(cwbvh::test::slurp(out), old);
            else EXPECT_FALSE(fs::exists(out));
            EXPECT_EQ(listing(dir), before);
        }
    }
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

/// A clock the test moves by hand, and what the phase line wrote.
struct FakeTerminal {
    PhaseLine::Clock::time_point now{std::chrono::seconds(1000)};
    std::mutex mutex;
    std::string text;
    PhaseLine::Write write() {
        return [this](const std::string& s) {
            const std::lock_guard<std::mutex> lock(mutex);
            text += s;
        };
    }
    PhaseLine::Now clock() {
        return [this] {
            const std::lock_guard<std::mutex> lock(mutex);
            return now;
        };
    }
    std::string take() {
        const std::lock_guard<std::mutex> lock(mutex);
        std::string t;
        t.swap(text);
        return t;
    }
};

TEST(PhaseLineClock, PercentagesOnlyAfterTheDelayAndOnlyWhenTheyMove) {
    using std::chrono::milliseconds;
    FakeTerminal term;
    Progress progress;
    PhaseLine line(progress, term.write(), term.clock(), /*ticker=*/false);
    progress.reset(200);
    line.on_phase("sbvh", false, 0.0);
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] sbvh ...");
    progress.add(50);
    line.tick();
    term.now += PhaseLine::kDelay;
    line.tick();  // exactly the delay: not yet
    EXPECT_EQ(term.take(), "");
    term.now += milliseconds(1);
    line.tick();
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] sbvh        25%");
    line.tick();  // same percentage: nothing
    term.now += PhaseLine::kTick;
    line.tick();
    EXPECT_EQ(term.take(), "");
    progress.add(149);  // 199 of 200: rounded down
    line.tick();
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] sbvh        99%");
    progress.add(1);
    line.tick();
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] sbvh       100%");
    line.on_phase("sbvh", true, 1.25);
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] sbvh          1.250 s\n");
    term.now += std::chrono::seconds(10);
    line.tick();  // no phase running
    EXPECT_EQ(term.take(), "");

    // A new phase starts its own delay and shows its first percentage even if it equals
    // the last one shown; an uncounted phase (total 0) shows none.
    progress.reset(4);
    line.on_phase("collapse", false, 0.0);
    term.take();
    progress.add(4);
    term.now += PhaseLine::kDelay;
    line.tick();
    EXPECT_EQ(term.take(), "");
    term.now += milliseconds(1);
    line.tick();
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] collapse   100%");
    line.on_phase("collapse", true, 2.0);
    progress.reset(0);
    line.on_phase("encode", false, 0.0);
    term.take();
    term.now += std::chrono::seconds(5);
    line.tick();
    EXPECT_EQ(term.take(), "");

    // Over-counting is clamped; after stop() nothing is written.
    progress.reset(10);
    line.on_phase("slots", false, 0.0);
    term.take();
    progress.add(25);
    term.now += std::chrono::seconds(2);
    line.tick();
    EXPECT_EQ(term.take(), "\r\033[K[cwbvhc] slots      100%");
    line.stop();
    line.on_phase("slots", true, 1.0);
    progress.reset(10);
    line.tick();
    EXPECT_EQ(term.take(), "");
}

TEST(PhaseLineClock, TheTickerThreadShowsThePercentageOnItsOwn) {
    // The ticker runs every kTick of real time but reads the injected clock: once the fake
    // clock is past the delay, a percentage must appear without any tick() from the test.
    // (Waits for it, up to 30 s: the outcome does not depend on the machine's speed.)
    FakeTerminal term;
    Progress progress;
    PhaseLine line(progress, term.write(), term.clock());
    progress.reset(3);
    line.on_phase("sbvh", false, 0.0);
    progress.add(1);
    {
        const std::lock_guard<std::mutex> lock(term.mutex);
        term.now += PhaseLine::kDelay + std::chrono::milliseconds(1);
    }
    std::string text;
    for (int i = 0; i < 3000 && text.find("33%") == std::string::npos; ++i) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
        const std::lock_guard<std::mutex> lock(term.mutex);
        text = term.text;
    }
    EXPECT_NE(text.find("\r\033[K[cwbvhc] sbvh        33%"), std::string::npos) << text;
    line.stop();
}

/// cwbvhc on a pseudo-terminal (util-linux `script`): the phase line shows every phase, any
/// percentages are in 0..100 and rise within a phase, nothing follows the summary, and the
/// file is the one a --quiet run through pipes writes.
TEST(CompileProgress, TerminalPhaseLineOnAPseudoTerminal) {
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
    // When a percentage shows depends on how long the phase takes on this machine: the
    // timing rules are tested with an injected clock (PhaseLine tests above); here only
    // what did show is checked.
    std::printf("sbvh percentage lines on the terminal: %d\n", sbvh_lines);

    const auto r = cwbvh::test::run_tool("cwbvhc", {dragon, "-o", quiet, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.err.empty());
    EXPECT_EQ(cwbvh::test::slurp(out), cwbvh::test::slurp(quiet));
}

}  // namespace
