// AtomicOutput (format/file_io.h), the one write path of every tool: an output replaces its
// path whole or not at all. Before it, `cwbvh rays`, `trace --hits`, `render` and the examples
// wrote straight into the target with fopen("wb"): a full disk left a 64 KiB prefix that
// looked valid (a PNG signature, a ray file header) over the previous file (hostile-input
// audit). A write failure is provoked here with RLIMIT_FSIZE (write() fails with EFBIG once
// SIGXFSZ is ignored).
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cwbvh/format/file_io.h"
#include "cwbvh/format/status.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

namespace fs = std::filesystem;

std::string slurp(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// Entries of `dir` whose name starts with `stem` (the output and any temporary file).
std::vector<std::string> entries(const std::string& dir, const std::string& stem) {
    std::vector<std::string> out;
    for (const auto& e : fs::directory_iterator(dir))
        if (e.path().filename().string().rfind(stem, 0) == 0) out.push_back(e.path().filename().string());
    return out;
}

TEST(AtomicOutput, ReplacesThePathOnlyOnCommit) {
    const std::string dir = test::temp_dir() + "/atomic_commit";
    fs::create_directories(dir);
    const std::string path = dir + "/out.bin";
    { std::ofstream(path) << "old"; }
    {
        Expected<AtomicOutput> out = AtomicOutput::create(path);
        ASSERT_TRUE(out.ok()) << out.error().message;
        ASSERT_TRUE(out->write("new contents", 12).ok());
        EXPECT_EQ(slurp(path), "old");  // not yet
        ASSERT_TRUE(out->commit().ok());
    }
    EXPECT_EQ(slurp(path), "new contents");
    EXPECT_EQ(entries(dir, "out.bin"), std::vector<std::string>{"out.bin"});
    // Dropped without commit: the old file stays, the temporary file goes.
    {
        Expected<AtomicOutput> out = AtomicOutput::create(path);
        ASSERT_TRUE(out.ok());
        ASSERT_TRUE(out->write("half", 4).ok());
    }
    EXPECT_EQ(slurp(path), "new contents");
    EXPECT_EQ(entries(dir, "out.bin"), std::vector<std::string>{"out.bin"});
    // write_file_atomic over an absent path.
    ASSERT_TRUE(write_file_atomic(dir + "/fresh.bin", "abc", 3).ok());
    EXPECT_EQ(slurp(dir + "/fresh.bin"), "abc");
}

TEST(AtomicOutput, AFailedWriteLeavesTheOldFileAndNoPartialFile) {
    const std::string dir = test::temp_dir() + "/atomic_fail";
    fs::create_directories(dir);
    const std::string path = dir + "/big.bin";
    { std::ofstream(path) << "previous"; }
    const std::vector<char> data(1 << 20, 'x');
    rlimit old{};
    ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old), 0);
    const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit small = old;
    small.rlim_cur = 4096;
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &small), 0);
    const Result r = write_file_atomic(path, data.data(), data.size());
    setrlimit(RLIMIT_FSIZE, &old);
    std::signal(SIGXFSZ, old_handler);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.rule, rule::kWriteFailed);
    EXPECT_EQ(r.message.rfind(path + ": write failed: ", 0), 0u) << r.message;
    EXPECT_EQ(slurp(path), "previous");
    EXPECT_EQ(entries(dir, "big.bin"), std::vector<std::string>{"big.bin"});
}

// A symlinked output is written through (the link stays, its target gets the bytes), and a
// read-only output is refused by check_output_path, which every tool calls first (a rename
// over it needs only the folder's permission).
TEST(AtomicOutput, SymlinksAreWrittenThroughAndReadOnlyOutputsRefused) {
    const std::string dir = test::temp_dir() + "/atomic_link";
    fs::remove_all(dir);
    fs::create_directories(dir + "/real");
    { std::ofstream(dir + "/real/target.bin") << "old"; }
    fs::create_symlink("real/target.bin", dir + "/link.bin");
    ASSERT_TRUE(write_file_atomic(dir + "/link.bin", "new", 3).ok());
    EXPECT_TRUE(fs::is_symlink(dir + "/link.bin"));
    EXPECT_EQ(slurp(dir + "/real/target.bin"), "new");
    EXPECT_EQ(entries(dir + "/real", "target.bin"), std::vector<std::string>{"target.bin"});
    // A dangling link: its target is created.
    fs::create_symlink("real/fresh.bin", dir + "/dangling.bin");
    ASSERT_TRUE(write_file_atomic(dir + "/dangling.bin", "x", 1).ok());
    EXPECT_EQ(slurp(dir + "/real/fresh.bin"), "x");
    // "link/.." is resolved by the kernel (link's target's parent), as same_file resolves it:
    // a lexical "a/link/.." -> "a" wrote another file than the one checked (a review found
    // cwbvhc replacing its own input through it).
    fs::create_directories(dir + "/work");
    fs::create_directories(dir + "/real/sub");
    fs::create_symlink("../real/sub", dir + "/work/link");
    { std::ofstream(dir + "/work/in.stl") << "input"; }
    ASSERT_TRUE(check_output_path(dir + "/work/link/../in.stl", {dir + "/work/in.stl"}).ok());
    ASSERT_TRUE(write_file_atomic(dir + "/work/link/../in.stl", "out", 3).ok());
    EXPECT_EQ(slurp(dir + "/work/in.stl"), "input");
    EXPECT_EQ(slurp(dir + "/real/in.stl"), "out");
    // A replaced file keeps its permission bits.
    fs::permissions(dir + "/real/in.stl", fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
    ASSERT_TRUE(write_file_atomic(dir + "/real/in.stl", "again", 5).ok());
    EXPECT_EQ(fs::status(dir + "/real/in.stl").permissions(),
              fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
    if (::geteuid() != 0) {  // root writes anything
        fs::permissions(dir + "/real/target.bin", fs::perms::owner_read);
        const Result r = check_output_path(dir + "/real/target.bin", {});
        EXPECT_FALSE(r.ok());
        EXPECT_NE(r.message.find("output exists and is not writable"), std::string::npos) << r.message;
    }
    EXPECT_FALSE(check_output_path("", {}).ok());
    const Result missing = check_output_path(dir + "/no/such/folder/out.bin", {});
    EXPECT_NE(missing.message.find("output folder '" + dir + "/no/such/folder' does not exist"), std::string::npos)
        << missing.message;
}

TEST(AtomicOutput, AnUncreatableOutputNamesThePath) {
    const std::string path = test::temp_dir() + "/no_such_dir/out.bin";
    const Result r = write_file_atomic(path, "x", 1);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.rule, rule::kOpenFailed);
    EXPECT_EQ(r.message.rfind(path + ": cannot create ", 0), 0u) << r.message;
    EXPECT_NE(r.message.find("No such file or directory"), std::string::npos) << r.message;
}

}  // namespace
}  // namespace cwbvh
