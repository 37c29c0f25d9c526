// The `cwbvh` command: exit codes and one-line errors.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>

#include "format/test_util.h"

namespace cwbvh {
namespace {

using test::ToolRun;
ToolRun run(const std::string& args) { return test::run_cwbvh(args); }
size_t lines(const std::string& s) { return test::count_lines(s); }

TEST(Cli, ValidateValidFile) {
    const std::string path = test::write_temp("cli_valid.cwbvh", test::synthetic_file());
    const ToolRun r = run("validate " + path);
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(r.out, path + ": valid\n");
}

TEST(Cli, ValidateInvalidFileGivesOneLine) {
    std::vector<uint8_t> bytes = test::synthetic_file();
    test::edit_element<CwbvhNode>(bytes, kSectionNodes, 0, [](CwbvhNode& n) { n.child_base = 0; });
    const std::string path = test::write_temp("cli_bad.cwbvh", bytes);
    const ToolRun r = run("validate " + path);
    EXPECT_EQ(r.code, 1);
    EXPECT_EQ(lines(r.out), 1u) << r.out;
    EXPECT_EQ(r.out.rfind("cwbvh: error: " + path + ": section NODE: node 0", 0), 0u) << r.out;
    EXPECT_NE(r.out.find("[rule 5105]"), std::string::npos) << r.out;
    const ToolRun missing = run("validate " + test::temp_dir() + "/nope.cwbvh");
    EXPECT_EQ(missing.code, 1);
    EXPECT_EQ(lines(missing.out), 1u) << missing.out;
}

TEST(Cli, NoChecksums) {
    std::vector<uint8_t> bytes = test::synthetic_file();
    const SectionEntry tris = test::entry(bytes, test::find_entry(bytes, kSectionTriangles));
    bytes[tris.offset] ^= 1;  // lowest mantissa bit of v0.x
    const std::string path = test::write_temp("cli_sum.cwbvh", bytes);
    EXPECT_EQ(run("validate " + path).code, 1);
    EXPECT_EQ(run("validate --no-checksums " + path).code, 0);
}

TEST(Cli, Info) {
    const std::string path = test::write_temp("cli_info.cwbvh", test::synthetic_file());
    const ToolRun text = run("info " + path);
    EXPECT_EQ(text.code, 0) << text.out;
    EXPECT_NE(text.out.find("version 1.0"), std::string::npos) << text.out;
    EXPECT_NE(text.out.find("NODE"), std::string::npos);
    EXPECT_NE(text.out.find("bounds:"), std::string::npos);
    EXPECT_NE(text.out.find("C_prim 0.300000012"), std::string::npos) << text.out;
    const ToolRun json = run("info --json " + path);
    EXPECT_EQ(json.code, 0);
    EXPECT_NE(json.out.find("\"type\": \"TRIS\""), std::string::npos) << json.out;
    EXPECT_NE(json.out.find("\"build_info\""), std::string::npos);
}

TEST(Cli, UsageErrors) {
    EXPECT_EQ(run("").code, 2);
    EXPECT_EQ(run("frobnicate x").code, 2);
    EXPECT_EQ(run("info").code, 2);
    EXPECT_EQ(run("info a b").code, 2);
    EXPECT_EQ(run("validate").code, 2);
    EXPECT_EQ(run("validate --bogus x").code, 2);
    EXPECT_EQ(run("--help").code, 0);
}

// trace's A/B options change the CWBVH kernel on the GPU: on the CPU or with --bvh2 they are a
// usage error (exit 2, one line that says so), as are --no-defer-hits with the fast test (which
// never defers: the same kernel twice) and a postponing threshold above 100.
TEST(Cli, TraceKernelOptionsNeedTheGpuKernel) {
    const std::string path = test::write_temp("cli_ab.cwbvh", test::synthetic_file());
    const std::string rays = test::temp_dir() + "/cli_ab.rays";
    ASSERT_EQ(run("rays " + path + " --primary --width 8 --height 8 -o " + rays).code, 0);
    for (const std::string opt : {"--no-defer-hits", "--reference-node-test", "--postpone-percent 35"}) {
        for (const std::string where : {"", " --cpu", " --gpu --bvh2"}) {
            const ToolRun r = run("trace " + path + " --rays " + rays + " " + opt + where);
            EXPECT_EQ(r.code, 2) << opt << where << r.out;
            EXPECT_EQ(lines(r.out), 1u) << r.out;
            EXPECT_NE(r.out.find("they need --gpu, without --bvh2"), std::string::npos) << r.out;
        }
    }
    const ToolRun fast = run("trace " + path + " --rays " + rays + " --gpu --fast --no-defer-hits");
    EXPECT_EQ(fast.code, 2);
    EXPECT_NE(fast.out.find("never defers"), std::string::npos) << fast.out;
    const ToolRun high = run("trace " + path + " --rays " + rays + " --gpu --postpone-percent 101");
    EXPECT_EQ(high.code, 2);
    EXPECT_NE(high.out.find("[0, 100]"), std::string::npos) << high.out;
}

// `cwbvh VERB --help` prints the verb's usage and options to stdout and exits 0 (it was
// "unknown option --help", exit 2); `cwbvh --help` lists every verb with its options.
TEST(Cli, VerbHelp) {
    const ToolRun all = run("--help");
    EXPECT_NE(all.out.find("validate FILE... [--deep] [--no-checksums]"), std::string::npos) << all.out;
    for (const std::string verb : {"info", "validate", "rays", "trace", "model", "render"}) {
        for (const char* flag : {" --help", " -h"}) {
            const ToolRun r = run(verb + flag);
            EXPECT_EQ(r.code, 0) << verb << r.out;
            EXPECT_EQ(r.out.rfind("usage: cwbvh " + verb + " ", 0), 0u) << r.out;
            EXPECT_GT(test::count_lines(r.out), 2u) << r.out;
            EXPECT_NE(all.out.find("  cwbvh " + verb + " "), std::string::npos) << verb;
        }
    }
    // --help among other arguments is an unknown option, as before.
    EXPECT_EQ(run("info x.cwbvh --help").code, 2);
}

}  // namespace
}  // namespace cwbvh
