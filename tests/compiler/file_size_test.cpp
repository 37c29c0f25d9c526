// Output-size target (spec section 3.8): a default cwbvhc file, source map
// included, is at most 55 bytes per input triangle on a closed scanned mesh.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "compiler/cli_support.h"
#include "cwbvh/loader.h"

namespace fs = std::filesystem;

namespace {

TEST(FileSize, BunnyAtMost55BytesPerInputTriangle) {
    const char* bunny = cwbvh::test::bunny_path();
    if (!fs::exists(bunny)) GTEST_SKIP() << bunny << " not installed";
    const auto dir = cwbvh::test::temp_dir("filesize");
    const std::string out = (dir / "bunny.cwbvh").string();
    const auto r = cwbvh::test::run_tool("cwbvhc", {bunny, "-o", out, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    auto file = cwbvh::File::open(out);
    ASSERT_TRUE(file.ok()) << file.error().describe();
    ASSERT_NE(file->build_info(), nullptr);
    const uint64_t input = file->build_info()->input_triangles;
    ASSERT_GT(input, 0u);
    const uint64_t size = fs::file_size(out);
    std::printf("bunny: %llu bytes, %llu input triangles, %.2f B/triangle (TRIS %zu records, PMAP %zu ranges)\n",
                (unsigned long long)size, (unsigned long long)input, double(size) / double(input),
                file->triangles().size(), file->source_ranges().size());
    EXPECT_LE(size, 55 * input);
    // One closed mesh, nothing dropped: the whole source map is one range.
    EXPECT_EQ(file->source_ranges().size(), 1u);
    EXPECT_EQ(file->stored_triangle_count(), input);
}

}  // namespace
