// Issue 21 against cwbvhc: inputs that are not regular files (findings 2 and 7), glTF buffer
// URIs that leave the input's folder (finding 7) and the reasons of a failed import (finding 6).
// Every run goes through `timeout`, so a hang shows as exit 124 instead of a stuck suite.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "compiler/cli_support.h"

namespace {

namespace fs = std::filesystem;
using cwbvh::test::RunResult;
using cwbvh::test::shell_quote;
using cwbvh::test::slurp;

/// `cwbvhc ARGS` with a 20 s limit (exit 124: it hung).
RunResult cwbvhc(const std::vector<std::string>& args, const fs::path& dir) {
    std::string cmd = "timeout 20 " + shell_quote(std::string(CWBVH_BIN_DIR) + "/cwbvhc");
    for (const auto& a : args) cmd += " " + shell_quote(a);
    cmd += " >" + shell_quote((dir / "stdout").string()) + " 2>" + shell_quote((dir / "stderr").string());
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = slurp(dir / "stdout");
    r.err = slurp(dir / "stderr");
    return r;
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

/// A glTF with one triangle whose 36-byte position buffer is the external file `uri`.
std::string gltf_with_buffer(const std::string& uri) {
    return "{\"asset\":{\"version\":\"2.0\"},\"scenes\":[{\"nodes\":[0]}],\"scene\":0,\"nodes\":[{\"mesh\":0}],"
           "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"mode\":4}]}],"
           "\"buffers\":[{\"byteLength\":36,\"uri\":\"" + uri + "\"}],"
           "\"bufferViews\":[{\"buffer\":0,\"byteLength\":36}],"
           "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"type\":\"VEC3\",\"count\":3,"
           "\"min\":[0,0,0],\"max\":[1,1,0]}]}";
}

void write_triangle_bin(const fs::path& path) {
    const float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(v), sizeof v);
}

TEST(CwbvhcHostile, FifoAndDeviceInputsAreRefusedWithoutReading) {
    const fs::path dir = cwbvh::test::temp_dir("h21_fifo");
    const fs::path fifo = dir / "mesh.obj";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const RunResult f = cwbvhc({fifo.string(), "-o", (dir / "out.cwbvh").string()}, dir);
    EXPECT_EQ(f.exit_code, 1) << f.err;
    EXPECT_TRUE(contains(f.err, "mesh.obj: is a FIFO")) << f.err;
    if (fs::exists("/dev/zero")) {
        const fs::path zero = dir / "zero.stl";
        fs::create_symlink("/dev/zero", zero);
        const RunResult z = cwbvhc({zero.string(), "-o", (dir / "out.cwbvh").string()}, dir);
        EXPECT_EQ(z.exit_code, 1) << z.err;
        EXPECT_TRUE(contains(z.err, "zero.stl: is a device")) << z.err;
    }
    EXPECT_FALSE(fs::exists(dir / "out.cwbvh"));
}

TEST(CwbvhcHostile, GltfBufferUrisStayInTheInputsFolder) {
    const fs::path dir = cwbvh::test::temp_dir("h21_uri");
    fs::create_directories(dir / "scene" / "data");
    write_triangle_bin(dir / "outside.bin");
    write_triangle_bin(dir / "scene" / "data" / "inside.bin");
    auto compile = [&](const std::string& uri, std::vector<std::string> extra = {}) {
        const fs::path gltf = dir / "scene" / "t.gltf";
        std::ofstream(gltf) << gltf_with_buffer(uri);
        std::vector<std::string> args{gltf.string(), "-o", (dir / "out.cwbvh").string(), "--quiet"};
        args.insert(args.end(), extra.begin(), extra.end());
        return cwbvhc(args, dir);
    };
    const RunResult inside = compile("data/inside.bin");
    EXPECT_EQ(inside.exit_code, 0) << inside.err;

    const RunResult parent = compile("../outside.bin");
    EXPECT_EQ(parent.exit_code, 1) << parent.err;
    EXPECT_TRUE(contains(parent.err, "buffer URI '../outside.bin' leaves the input's folder")) << parent.err;
    const RunResult hidden = compile("data/../../outside.bin");
    EXPECT_EQ(hidden.exit_code, 1) << hidden.err;
    const RunResult encoded = compile("%2e%2e/outside.bin");  // tinygltf percent-decodes URIs
    EXPECT_EQ(encoded.exit_code, 1) << encoded.err;
    EXPECT_TRUE(contains(encoded.err, "'..'")) << encoded.err;
    const RunResult allowed = compile("../outside.bin", {"--allow-parent-uris"});
    EXPECT_EQ(allowed.exit_code, 0) << allowed.err;

    const RunResult absolute = compile((dir / "outside.bin").string());
    EXPECT_EQ(absolute.exit_code, 1) << absolute.err;
    EXPECT_TRUE(contains(absolute.err, "is absolute")) << absolute.err;
    const RunResult absolute_allowed = compile((dir / "outside.bin").string(), {"--allow-parent-uris"});
    EXPECT_EQ(absolute_allowed.exit_code, 1) << absolute_allowed.err;

    // A buffer that is a FIFO is refused, not waited on.
    ASSERT_EQ(::mkfifo((dir / "scene" / "data" / "fifo.bin").c_str(), 0600), 0);
    const RunResult fifo = compile("data/fifo.bin");
    EXPECT_EQ(fifo.exit_code, 1) << fifo.err;
}

TEST(CwbvhcHostile, FailedImportSaysWhyWithCappedWarnings) {
    const fs::path dir = cwbvh::test::temp_dir("h21_warn");
    // Every face is invalid: a repeated vertex, an index past the vertices.
    const fs::path bad = dir / "bad.obj";
    std::ofstream(bad) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\nf 2 2 3\nf 1 9 3\n";
    const RunResult r = cwbvhc({bad.string(), "-o", (dir / "out.cwbvh").string()}, dir);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_TRUE(contains(r.err, "cwbvhc: warning: " + bad.string() + ": ")) << r.err;
    EXPECT_TRUE(contains(r.err, "rejected all 3 faces")) << r.err;
    EXPECT_EQ(r.err.rfind("cwbvhc: error: "), r.err.find("cwbvhc: error: ")) << "one error line";

    // 25 inputs with a warning each, the last with nothing left: 20 warnings, then the count.
    std::vector<std::string> args;
    for (int i = 0; i < 25; ++i) {
        const fs::path p = dir / ("part" + std::to_string(i) + ".obj");
        std::ofstream(p) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 2\n";
        args.push_back(p.string());
    }
    args.push_back(bad.string());
    args.insert(args.end(), {"-o", (dir / "out.cwbvh").string()});
    const RunResult many = cwbvhc(args, dir);
    EXPECT_EQ(many.exit_code, 1) << many.err;
    EXPECT_EQ(cwbvh::test::count_lines(many.err), 22) << many.err;  // 20 + "... more" + the error
    EXPECT_TRUE(contains(many.err, "cwbvhc: warning: ... 7 more (27 warnings in all)")) << many.err;
}

// An output over a file the input names (hostile-input audit): `-o` over a glTF's external
// buffer replaced the scene's own data with a .cwbvh (exit 0), over its texture or an OBJ's
// material library the user's files. Each is refused before anything is read, and the file
// is left as it was; a statistics path in a missing folder is refused before the compile
// (it was reported after it, with the .cwbvh already written).
TEST(CwbvhcHostile, OutputsNeverReplaceFilesTheInputNames) {
    const fs::path dir = cwbvh::test::temp_dir("h21_referenced");
    fs::create_directories(dir / "tex dir");
    write_triangle_bin(dir / "tri.bin");
    std::string json = gltf_with_buffer("tri.bin");
    json.insert(json.size() - 1, ",\"images\":[{\"uri\":\"tex%20dir/t.png\"},{\"uri\":\"data:image/png;base64,AA==\"}]");
    { std::ofstream(dir / "scene.gltf") << json; }
    { std::ofstream(dir / "tex dir" / "t.png") << "png"; }
    for (const fs::path& target : {dir / "tri.bin", dir / "tex dir" / "t.png", dir / "tex dir" / ".." / "tri.bin"}) {
        const std::string before = slurp(dir / "tri.bin") + slurp(dir / "tex dir" / "t.png");
        const RunResult r = cwbvhc({(dir / "scene.gltf").string(), "-o", target.string()}, dir);
        EXPECT_EQ(r.exit_code, 1) << target << r.err;
        EXPECT_TRUE(contains(r.err, "refusing to overwrite it")) << r.err;
        EXPECT_EQ(slurp(dir / "tri.bin") + slurp(dir / "tex dir" / "t.png"), before);
    }
    // OBJ: its mtllib files.
    { std::ofstream(dir / "m.obj") << "mtllib my.mtl other.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"; }
    { std::ofstream(dir / "my.mtl") << "newmtl a\n"; }
    // OpenMesh opens the rest of the line as one name ("my.mtl other.mtl"); an existing file of
    // either spelling is guarded. A named file that does not exist is not: nothing is replaced.
    { std::ofstream(dir / "my.mtl other.mtl") << "newmtl b\n"; }
    for (const char* mtl : {"my.mtl", "my.mtl other.mtl"}) {
        const RunResult r = cwbvhc({(dir / "m.obj").string(), "-o", (dir / mtl).string()}, dir);
        EXPECT_EQ(r.exit_code, 1) << r.err;
        EXPECT_TRUE(contains(r.err, "which the input names; refusing to overwrite it")) << r.err;
    }
    EXPECT_EQ(slurp(dir / "my.mtl"), "newmtl a\n");
    EXPECT_EQ(slurp(dir / "my.mtl other.mtl"), "newmtl b\n");
    // The statistics, too, and a missing folder is refused before the compile: no .cwbvh.
    RunResult r = cwbvhc({(dir / "scene.gltf").string(), "-o", (dir / "s.cwbvh").string(), "--stats-json",
                          (dir / "tri.bin").string()}, dir);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    r = cwbvhc({(dir / "scene.gltf").string(), "-o", (dir / "s.cwbvh").string(), "--stats-json",
                (dir / "nodir" / "st.json").string()}, dir);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_TRUE(contains(r.err, "output folder")) << r.err;
    EXPECT_FALSE(fs::exists(dir / "s.cwbvh"));
    // A plain compile of the same scene works and leaves the referenced files alone.
    r = cwbvhc({(dir / "scene.gltf").string(), "-o", (dir / "s.cwbvh").string(), "-q"}, dir);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "s.cwbvh"));
}

}  // namespace
