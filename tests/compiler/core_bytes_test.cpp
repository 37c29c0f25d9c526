// One producer of file bytes: a scene compiled through the compiler core's API
// (core.h, after the importer front end) gives byte for byte the file that the
// cwbvhc executable writes for the same input and settings.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "../result_util.h"
#include "compiler/cli_support.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/core.h"
#include "cwbvh/compiler/import.h"

namespace cwbvh::compiler {
namespace {

struct Case {
    std::string name;
    std::vector<std::string> flags;  ///< cwbvhc flags
    CoreOptions core;                ///< the same settings for the core
    bool embree = false;             ///< binary tree from build_embree (front end) instead of build_sbvh
};

std::vector<Case> cases() {
    std::vector<Case> out;
    out.push_back({"default", {}, {}, false});
    Case keep{"keep-sbvh-keep-mesh", {"--keep-sbvh", "--keep-mesh"}, {}, false};
    keep.core.emit.bvh2 = Bvh2Section::kLeafRanges;
    keep.core.emit.keep_mesh = true;
    out.push_back(keep);
    Case greedy{"greedy-no-splits", {"--collapse", "greedy", "--split-alpha", "1", "--collapse-cost-prim", "0.5"},
                {}, false};
    greedy.core.collapse.kind = kCollapseGreedy;
    greedy.core.collapse.cost_prim = 0.5f;
    greedy.core.sbvh.split_alpha = 1.0f;
    out.push_back(greedy);
    Case embree{"embree", {"--builder", "embree", "--keep-sbvh"}, {}, true};
    embree.core.emit.builder = kBuilderEmbree;
    embree.core.emit.bvh2 = Bvh2Section::kLeafRanges;
    out.push_back(embree);
    return out;
}

/// The file bytes through the core API: import (front end), binary builder, core.
std::string core_file(const std::string& input, const Case& c) {
    Scene scene;
    std::string error;
    std::vector<std::string> warnings;
    EXPECT_TRUE(::cwbvh::test::ok(import_scene({input}, ImportOptions{}, scene, warnings), error)) << error;
    BinaryBvh binary;
    const bool built = c.embree ? ::cwbvh::test::ok(build_embree(scene, c.core.sbvh, binary), error)
                                : ::cwbvh::test::ok(build_sbvh(scene, c.core.sbvh, binary), error);
    EXPECT_TRUE(built) << error;
    EmitResult encoded;
    EXPECT_TRUE(::cwbvh::test::ok(compile_binary(scene, binary, c.core, encoded), error)) << error;
    std::vector<uint8_t> bytes;
    EXPECT_TRUE(::cwbvh::test::ok(scene_bytes(scene, encoded, bytes), error)) << error;
    return std::string(bytes.begin(), bytes.end());
}

void expect_same_bytes(const std::string& input, const std::filesystem::path& dir) {
    for (const Case& c : cases()) {
        SCOPED_TRACE(c.name);
        const std::string out = (dir / (c.name + ".cwbvh")).string();
        std::vector<std::string> args{input, "-o", out, "--quiet"};
        args.insert(args.end(), c.flags.begin(), c.flags.end());
        const test::RunResult r = test::run_tool("cwbvhc", args);
        ASSERT_EQ(r.exit_code, 0) << r.err;
        const std::string from_cli = test::slurp(out);
        const std::string from_core = core_file(input, c);
        ASSERT_FALSE(from_cli.empty());
        EXPECT_EQ(from_core.size(), from_cli.size());
        EXPECT_TRUE(from_core == from_cli) << "the core and cwbvhc wrote different bytes";
    }
}

TEST(CoreBytes, GeneratedMeshSameAsCwbvhc) {
    // A bumpy sphere of large triangles next to small ones: spatial splits,
    // several levels, leaves of 1-3 triangles.
    const auto dir = test::temp_dir("core_bytes");
    std::vector<std::array<double, 3>> v;
    std::vector<std::array<int, 3>> f;
    const int n = 24;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            const double th = M_PI * j / n, ph = 2 * M_PI * i / n, r = 1.0 + 0.1 * ((i * 7 + j * 3) % 5);
            v.push_back({r * std::sin(th) * std::cos(ph), r * std::sin(th) * std::sin(ph), r * std::cos(th)});
        }
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
            f.push_back({a, b, c});
            f.push_back({a, c, d});
        }
    const int base = int(v.size());  // one long sliver across the sphere
    v.push_back({-3, -0.1, 0});
    v.push_back({3, 0.1, 0.05});
    v.push_back({3, -0.1, -0.05});
    f.push_back({base, base + 1, base + 2});
    const std::string input = (dir / "sphere.obj").string();
    test::write_obj(input, v, f);
    expect_same_bytes(input, dir);
}

TEST(CoreBytes, BunnySameAsCwbvhc) {
    if (!std::filesystem::exists(test::bunny_path())) GTEST_SKIP() << test::bunny_path() << " not present";
    expect_same_bytes(test::bunny_path(), test::temp_dir("core_bytes_bunny"));
}

}  // namespace
}  // namespace cwbvh::compiler
