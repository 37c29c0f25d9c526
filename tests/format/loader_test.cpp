// cwbvh::File: mmap path, bad paths, section selection, move semantics.
#include <gtest/gtest.h>

#include <filesystem>

#include "cwbvh/loader/loader.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

TEST(Loader, OpensValidFileAndHandsOutSections) {
    const SceneData scene = make_synthetic_scene({});
    const std::string path = test::write_temp("valid.cwbvh", test::file_bytes(scene));
    auto f = File::open(path);
    ASSERT_TRUE(f.ok()) << f.error().describe();
    EXPECT_EQ(f->nodes().size(), scene.nodes.size());
    EXPECT_EQ(f->triangles().size(), scene.triangles.size());
    EXPECT_EQ(f->source_ranges().size(), scene.source_ranges.size());
    EXPECT_EQ(f->stored_triangle_count(), scene.triangles.size());  // synthetic: one reference each
    ASSERT_NE(f->bounds(), nullptr);
    EXPECT_EQ(f->bounds()->hi[1], scene.bounds.hi[1]);
    ASSERT_NE(f->build_info(), nullptr);
    EXPECT_EQ(f->build_info()->wide_nodes, scene.nodes.size());
    EXPECT_EQ(f->bvh2().size(), scene.bvh2.size());
    EXPECT_EQ(f->vertices().size(), scene.vertices.size());
    EXPECT_EQ(f->indices().size(), scene.indices.size());
    EXPECT_EQ(std::string(f->source_names().data(), f->source_names().size()), scene.source_names);
    EXPECT_EQ(std::memcmp(f->triangles().data(), scene.triangles.data(), scene.triangles.size() * sizeof(TriangleRecord)), 0);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(f->nodes().data()) % 64, 0u);
}

TEST(Loader, MoveOnlyRaii) {
    const std::string path = test::write_temp("move.cwbvh", test::synthetic_file());
    auto f = File::open(path);
    ASSERT_TRUE(f.ok());
    File a = std::move(*f);
    EXPECT_TRUE(f->nodes().empty());
    File b;
    b = std::move(a);
    EXPECT_FALSE(b.nodes().empty());
    EXPECT_TRUE(a.nodes().empty());
    static_assert(!std::is_copy_constructible_v<File>);
}

void expect_open_error(const std::string& path, uint32_t rule_id, const char* words) {
    auto f = File::open(path);
    ASSERT_FALSE(f.ok()) << path;
    EXPECT_EQ(f.error().rule, rule_id) << f.error().describe();
    EXPECT_EQ(f.error().message.rfind(path, 0), 0u) << "message starts with the path: " << f.error().message;
    EXPECT_NE(f.error().message.find(words), std::string::npos) << f.error().message;
}

TEST(Loader, RejectsBadPaths) {
    expect_open_error(test::temp_dir() + "/does-not-exist.cwbvh", rule::kOpenFailed, "cannot open");
    expect_open_error(test::temp_dir(), rule::kNotRegularFile, "directory");
    expect_open_error(test::write_temp("empty.cwbvh", {}), rule::kEmptyFile, "empty");
    const std::string text = "solid cube\nfacet normal 0 0 1\n";
    expect_open_error(test::write_temp("text.cwbvh", std::vector<uint8_t>(text.begin(), text.end())), rule::kBadMagic,
                      "not a cwbvh file");
    if (std::filesystem::exists("/dev/null")) expect_open_error("/dev/null", rule::kNotRegularFile, "regular");
}

TEST(Loader, SelectedSectionsOnly) {
    std::vector<uint8_t> bytes = test::synthetic_file();
    test::edit_element<uint32_t>(bytes, kSectionIndices, 0, [](uint32_t& i) { i = 12345; });
    const std::string path = test::write_temp("select.cwbvh", bytes);
    EXPECT_EQ(File::open(path).error().rule, rule::kIndexRange);
    OpenOptions o;
    o.sections = kMaskNodes | kMaskTriangles;
    auto f = File::open(path, o);
    ASSERT_TRUE(f.ok()) << f.error().describe();
    EXPECT_FALSE(f->nodes().empty());
    EXPECT_FALSE(f->triangles().empty());
    EXPECT_TRUE(f->indices().empty());
    EXPECT_EQ(f->bounds(), nullptr);
}

}  // namespace
}  // namespace cwbvh
