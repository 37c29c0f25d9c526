// End-to-end tests of the cwbvhc command: exit codes, one-line errors,
// refusing to write over its inputs, determinism across thread counts,
// --stats-json, and that what it writes passes the loader's full validation.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <filesystem>

#include <nlohmann/json.hpp>

#include "compiler/cli_support.h"
#include "cwbvh/loader/loader.h"

namespace fs = std::filesystem;
using cwbvh::test::count_lines;
using cwbvh::test::run_tool;

namespace {

std::vector<std::array<double, 3>> quad_vertices() { return {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}}; }

TEST(CwbvhcCli, UsageErrorsExitTwo) {
    EXPECT_EQ(run_tool("cwbvhc", {}).exit_code, 2);
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj"}).exit_code, 2);                     // no -o
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o"}).exit_code, 2);               // -o without value
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o", "x", "--bogus"}).exit_code, 2);
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o", "x", "--threads", "0"}).exit_code, 2);
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o", "x", "--builder", "magic"}).exit_code, 2);
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o", "x", "--split-alpha", "nan"}).exit_code, 2);
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o", "x", "--max-reference-growth", "-1"}).exit_code, 2);
    EXPECT_EQ(run_tool("cwbvhc", {"a.obj", "-o", "x", "--max-reference-growth", "inf"}).exit_code, 2);
    const auto help = run_tool("cwbvhc", {"--help"});
    EXPECT_EQ(help.exit_code, 0);
    EXPECT_NE(help.out.find("usage: cwbvhc"), std::string::npos);
}

TEST(CwbvhcCli, BadInputExitsOneWithOneLineNamingTheFile) {
    const auto dir = cwbvh::test::temp_dir("badinput");
    const auto out = (dir / "out.cwbvh").string();

    const auto missing = run_tool("cwbvhc", {(dir / "missing.obj").string(), "-o", out});
    EXPECT_EQ(missing.exit_code, 1);
    EXPECT_EQ(count_lines(missing.err), 1) << missing.err;
    EXPECT_NE(missing.err.find("missing.obj"), std::string::npos);

    const auto garbage_path = dir / "garbage.glb";
    std::ofstream(garbage_path) << "this is not a mesh";
    const auto garbage = run_tool("cwbvhc", {garbage_path.string(), "-o", out});
    EXPECT_EQ(garbage.exit_code, 1);
    EXPECT_EQ(count_lines(garbage.err), 1) << garbage.err;
    EXPECT_NE(garbage.err.find("garbage.glb"), std::string::npos);

    // Only degenerate triangles: nothing left to compile.
    const auto flat_path = dir / "degenerate.obj";
    cwbvh::test::write_obj(flat_path, {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}}, {{0, 1, 2}});
    const auto flat = run_tool("cwbvhc", {flat_path.string(), "-o", out});
    EXPECT_EQ(flat.exit_code, 1);
    EXPECT_EQ(count_lines(flat.err), 1) << flat.err;

    // A directory as input.
    const auto directory = run_tool("cwbvhc", {dir.string(), "-o", out});
    EXPECT_EQ(directory.exit_code, 1);
    EXPECT_FALSE(fs::exists(out)) << "no output may be written on failure";
}

// Writing over an input must fail before anything is read or written: exit 1 (bad input:
// the arguments parse, the files they name are wrong), one line naming the output, and the
// input left byte-identical.
void expect_refused(const cwbvh::test::RunResult& r, const fs::path& input, const std::string& before,
                    const std::string& named) {
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_EQ(count_lines(r.err), 1) << r.err;
    EXPECT_EQ(r.err.rfind("cwbvhc: error: " + named + ": ", 0), 0u) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_EQ(cwbvh::test::slurp(input), before) << "the input was changed";
}

TEST(CwbvhcCli, RefusesToWriteOverAnInput) {
    const auto dir = cwbvh::test::temp_dir("overwrite");
    const auto mesh = dir / "a.obj";
    cwbvh::test::write_obj(mesh, quad_vertices(), {{0, 1, 2}, {0, 2, 3}});
    const std::string before = cwbvh::test::slurp(mesh);
    ASSERT_FALSE(before.empty());

    // Same path, absolute and relative.
    expect_refused(run_tool("cwbvhc", {mesh.string(), "-o", mesh.string()}), mesh, before, mesh.string());
    expect_refused(run_tool("cwbvhc", {"a.obj", "-o", "a.obj"}, dir), mesh, before, "a.obj");
    // The same file by another spelling: ./, a detour through a subdirectory, absolute vs relative.
    fs::create_directories(dir / "sub");
    expect_refused(run_tool("cwbvhc", {"a.obj", "-o", "./a.obj"}, dir), mesh, before, "./a.obj");
    expect_refused(run_tool("cwbvhc", {"./a.obj", "-o", "sub/../a.obj"}, dir), mesh, before, "sub/../a.obj");
    expect_refused(run_tool("cwbvhc", {mesh.string(), "-o", "../a.obj"}, dir / "sub"), mesh, before, "../a.obj");
    // A symlink to the input, either way round.
    fs::create_symlink(mesh, dir / "link.obj");
    expect_refused(run_tool("cwbvhc", {mesh.string(), "-o", (dir / "link.obj").string()}), mesh, before,
                   (dir / "link.obj").string());
    expect_refused(run_tool("cwbvhc", {(dir / "link.obj").string(), "-o", mesh.string()}), mesh, before,
                   mesh.string());
    // A hard link: another name, same device and inode.
    fs::create_hard_link(mesh, dir / "hard.obj");
    expect_refused(run_tool("cwbvhc", {mesh.string(), "-o", (dir / "hard.obj").string()}), mesh, before,
                   (dir / "hard.obj").string());
    EXPECT_EQ(cwbvh::test::slurp(dir / "hard.obj"), before);
    // Any of several inputs counts, not only the first.
    const auto other = dir / "b.obj";
    cwbvh::test::write_obj(other, quad_vertices(), {{0, 1, 2}});
    expect_refused(run_tool("cwbvhc", {other.string(), mesh.string(), "-o", (dir / "hard.obj").string()}), mesh,
                   before, (dir / "hard.obj").string());
    // --stats-json is an output too.
    expect_refused(run_tool("cwbvhc", {"a.obj", "-o", "x.cwbvh", "--stats-json", "./link.obj"}, dir), mesh, before,
                   "./link.obj");
    EXPECT_FALSE(fs::exists(dir / "x.cwbvh")) << "nothing may be written when an output is refused";
}

TEST(CwbvhcCli, OutputMustBeARegularFileOrNew) {
    const auto dir = cwbvh::test::temp_dir("output_kind");
    const auto mesh = dir / "a.obj";
    cwbvh::test::write_obj(mesh, quad_vertices(), {{0, 1, 2}, {0, 2, 3}});
    const std::string before = cwbvh::test::slurp(mesh);

    fs::create_directories(dir / "out_dir");
    const auto to_dir = run_tool("cwbvhc", {mesh.string(), "-o", (dir / "out_dir").string()});
    expect_refused(to_dir, mesh, before, (dir / "out_dir").string());
    EXPECT_NE(to_dir.err.find("directory"), std::string::npos) << to_dir.err;

    const auto fifo = dir / "out_fifo";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const auto to_fifo = run_tool("cwbvhc", {mesh.string(), "-o", fifo.string()});
    expect_refused(to_fifo, mesh, before, fifo.string());
    EXPECT_NE(to_fifo.err.find("not a regular file"), std::string::npos) << to_fifo.err;
    EXPECT_TRUE(fs::is_fifo(fifo)) << "the fifo must not be replaced";

    // An existing, unrelated regular file is replaced as before.
    const auto out = dir / "out.cwbvh";
    std::ofstream(out) << "stale";
    const auto r = run_tool("cwbvhc", {mesh.string(), "-o", out.string(), "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto file = cwbvh::File::open(out.string());
    ASSERT_TRUE(file.ok()) << file.error().describe();
    EXPECT_EQ(file->stored_triangle_count(), 2u);
    EXPECT_EQ(cwbvh::test::slurp(mesh), before);
}

TEST(CwbvhcCli, StatsJsonHasTheDocumentedKeysAndMatchesTheFile) {
    const auto dir = cwbvh::test::temp_dir("stats");
    const auto mesh = dir / "quad.obj";
    auto vertices = quad_vertices();
    vertices.push_back({2, 0, 0});  // collinear with vertices 0 and 1
    cwbvh::test::write_obj(mesh, vertices, {{0, 1, 2}, {0, 2, 3}, {0, 1, 4}});  // one degenerate (zero area)
    const auto out = (dir / "quad.cwbvh").string();
    const auto json_path = (dir / "stats.json").string();
    const auto r = run_tool("cwbvhc", {mesh.string(), "-o", out, "--stats-json", json_path, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(r.out.empty()) << "--quiet prints nothing";

    const auto j = nlohmann::json::parse(cwbvh::test::slurp(json_path));
    for (const char* key : {"input_triangles", "dropped_triangles", "triangles", "references", "binary_nodes",
                            "wide_nodes", "avg_children", "max_leaf_triangles", "sah_binary", "sah_wide", "bytes",
                            "seconds", "peak_rss_bytes"})
        EXPECT_TRUE(j.contains(key)) << key;
    for (const char* phase : {"import", "sbvh", "collapse", "slots", "encode", "write"}) {
        EXPECT_TRUE(j["peak_rss_after"].contains(phase)) << phase;
        EXPECT_TRUE(j["rss_after"].contains(phase)) << phase;
        EXPECT_GT(j["rss_after"][phase].get<uint64_t>(), 0u) << phase;  // /proc/self/statm (Linux)
    }
    EXPECT_EQ(j["input_triangles"], 3);
    EXPECT_EQ(j["dropped_triangles"]["degenerate"], 1);
    EXPECT_EQ(j["triangles"], 2);
    EXPECT_TRUE(j["bytes"].contains("NODE"));
    EXPECT_TRUE(j["seconds"].contains("sbvh"));

    auto file = cwbvh::File::open(out);
    ASSERT_TRUE(file.ok()) << file.error().describe();
    EXPECT_EQ(file->nodes().size(), j["wide_nodes"].get<size_t>());
    EXPECT_EQ(file->triangles().size(), j["references"].get<size_t>());
    EXPECT_EQ(file->stored_triangle_count(), 2u);
    ASSERT_TRUE(file->source_of(1).has_value());
    EXPECT_FALSE(file->source_of(2).has_value());
    ASSERT_NE(file->build_info(), nullptr);
    EXPECT_EQ(file->build_info()->dropped_degenerate, 1u);
    EXPECT_TRUE(file->bvh2().empty()) << "BVH2 only with --keep-sbvh";
}

TEST(CwbvhcCli, FacesTheReaderRejectsAreCountedNotLost) {
    // OpenMesh drops a face with a repeated vertex index and cannot parse "nan";
    // the totals must still account for every face the file declares.
    const auto dir = cwbvh::test::temp_dir("rejected");
    const auto mesh = dir / "rejected.obj";
    std::ofstream(mesh) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\nf 1 1 2\n";
    const auto json_path = (dir / "stats.json").string();
    const auto r = run_tool("cwbvhc", {mesh.string(), "-o", (dir / "x.cwbvh").string(), "--stats-json", json_path,
                                       "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(cwbvh::test::slurp(json_path));
    EXPECT_EQ(j["input_triangles"], 3);
    EXPECT_EQ(j["dropped_triangles"]["rejected_by_reader"], 1);
    EXPECT_EQ(j["triangles"], 2);
}

TEST(CwbvhcCli, OptionalSectionsOnlyWhenAsked) {
    const auto dir = cwbvh::test::temp_dir("optional");
    const auto mesh = dir / "quad.obj";
    cwbvh::test::write_obj(mesh, quad_vertices(), {{0, 1, 2}, {0, 2, 3}});
    const auto out = (dir / "quad.cwbvh").string();
    ASSERT_EQ(run_tool("cwbvhc", {mesh.string(), "-o", out, "--keep-sbvh", "--keep-mesh", "--quiet"}).exit_code, 0);
    auto file = cwbvh::File::open(out);
    ASSERT_TRUE(file.ok()) << file.error().describe();
    EXPECT_FALSE(file->bvh2().empty());
    EXPECT_EQ(file->vertices().size(), 4u * 3u);
    EXPECT_EQ(file->indices().size(), 2u * 3u);
}

TEST(CwbvhcCli, ByteIdenticalOutputForAnyThreadCountAndBuilder) {
    if (!fs::exists(cwbvh::test::bunny_path())) GTEST_SKIP() << "glmark2-data bunny not installed";
    const auto dir = cwbvh::test::temp_dir("determinism");
    for (const char* builder : {"sbvh", "embree"}) {
        const auto one = (dir / (std::string(builder) + "1.cwbvh")).string();
        const auto two = (dir / (std::string(builder) + "2.cwbvh")).string();
        ASSERT_EQ(run_tool("cwbvhc", {cwbvh::test::bunny_path(), "-o", one, "--threads", "1", "--builder", builder,
                                      "--keep-sbvh", "--quiet"})
                      .exit_code,
                  0);
        ASSERT_EQ(run_tool("cwbvhc", {cwbvh::test::bunny_path(), "-o", two, "--threads", "2", "--builder", builder,
                                      "--keep-sbvh", "--quiet"})
                      .exit_code,
                  0);
        EXPECT_EQ(cwbvh::test::slurp(one), cwbvh::test::slurp(two)) << builder << ": output depends on threads";
        const auto validate = run_tool("cwbvh", {"validate", "--deep", one});
        EXPECT_EQ(validate.exit_code, 0) << validate.out << validate.err;
    }
}

}  // namespace
