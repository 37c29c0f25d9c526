// Writer: layout, determinism, round trip of every section type, errors.
#include <gtest/gtest.h>

#include <filesystem>

#include "cwbvh/format/sections.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

template <class T>
std::vector<T> section_as(const FileLayout& l, uint32_t type) {
    const SectionEntry* e = l.find(type);
    EXPECT_NE(e, nullptr) << section_name(type);
    if (e == nullptr) return {};
    std::vector<T> out(e->size / sizeof(T));
    if (!out.empty()) std::memcpy(out.data(), l.payload(*e).data(), e->size);
    return out;
}

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

TEST(Writer, RoundTripsEverySection) {
    const SceneData scene = make_synthetic_scene({});
    const std::vector<uint8_t> f = test::file_bytes(scene);
    FileLayout l;
    const Result r = validate(f, {}, &l);
    ASSERT_TRUE(r.ok()) << r.describe();
    EXPECT_EQ(l.table.size(), 9u);
    EXPECT_TRUE(same_bytes(section_as<CwbvhNode>(l, kSectionNodes), scene.nodes));
    EXPECT_TRUE(same_bytes(section_as<TriangleRecord>(l, kSectionTriangles), scene.triangles));
    EXPECT_TRUE(same_bytes(section_as<SourceRange>(l, kSectionSourceMap), scene.source_ranges));
    EXPECT_TRUE(same_bytes(section_as<SceneBounds>(l, kSectionBounds), std::vector<SceneBounds>{scene.bounds}));
    EXPECT_TRUE(same_bytes(section_as<BuildInfo>(l, kSectionBuildInfo), std::vector<BuildInfo>{*scene.build_info}));
    EXPECT_TRUE(same_bytes(section_as<Bvh2Node>(l, kSectionBvh2), scene.bvh2));
    EXPECT_TRUE(same_bytes(section_as<float>(l, kSectionVertices), scene.vertices));
    EXPECT_TRUE(same_bytes(section_as<uint32_t>(l, kSectionIndices), scene.indices));
    const auto names = section_as<char>(l, kSectionSourceNames);
    EXPECT_EQ(std::string(names.begin(), names.end()), scene.source_names);
}

TEST(Writer, LayoutFollowsTheSpec) {
    const std::vector<uint8_t> f = test::synthetic_file();
    const FileHeader h = test::header_of(f);
    EXPECT_EQ(std::memcmp(h.magic, kMagic, 12), 0);
    EXPECT_EQ(h.header_size, 64u);
    EXPECT_EQ(h.section_table_offset, 64u);
    EXPECT_EQ(h.file_size, f.size());
    uint64_t end = 64 + h.section_count * sizeof(SectionEntry);
    for (uint32_t i = 0; i < h.section_count; ++i) {
        const SectionEntry e = test::entry(f, i);
        EXPECT_EQ(e.offset % 64, 0u);
        EXPECT_GE(e.offset, end);
        EXPECT_LT(e.offset - end, 64u);  // padding only
        EXPECT_EQ(e.checksum, payload_checksum(f.data() + e.offset, e.size));
        end = e.offset + e.size;
    }
    EXPECT_EQ(end, f.size());
}

TEST(Writer, IsDeterministicAndFileMatchesMemory) {
    const SceneData scene = make_synthetic_scene({});
    Writer w;
    add_scene_sections(w, scene);
    std::vector<uint8_t> a, b;
    ASSERT_TRUE(w.to_bytes(a).ok());
    ASSERT_TRUE(w.to_bytes(b).ok());
    EXPECT_EQ(a, b);
    const std::string path = test::temp_dir() + "/det.cwbvh";
    ASSERT_TRUE(w.write_file(path).ok());
    std::vector<uint8_t> c(std::filesystem::file_size(path));
    FILE* fp = std::fopen(path.c_str(), "rb");
    ASSERT_NE(fp, nullptr);
    ASSERT_EQ(std::fread(c.data(), 1, c.size(), fp), c.size());
    std::fclose(fp);
    EXPECT_EQ(a, c);
    for (const auto& entry : std::filesystem::directory_iterator(test::temp_dir()))
        EXPECT_EQ(entry.path().string().find(".tmp."), std::string::npos) << "temporary left behind";
}

TEST(Writer, RejectsBadSections) {
    const uint8_t bytes[16] = {};
    {
        Writer w;
        w.add_section(fourcc('A', 'B', 'C', 'D'), 0, 4, 4, bytes);
        w.add_section(fourcc('A', 'B', 'C', 'D'), 0, 4, 4, bytes);
        std::vector<uint8_t> out;
        const Result r = w.to_bytes(out);
        EXPECT_EQ(r.status, Status::kInvalidArgument);
        EXPECT_NE(r.message.find("ABCD"), std::string::npos) << r.message;
    }
    {
        Writer w;
        w.add_section(fourcc('A', 'B', 'C', 'D'), 0, 4, 5, bytes);  // 20 != 16
        std::vector<uint8_t> out;
        EXPECT_EQ(w.to_bytes(out).rule, rule::kSectionSize);
    }
    {
        Writer w;
        w.add_section(kSectionNodes, kSectionRequired, 16, 1, bytes);  // NODE elements are 80 bytes
        std::vector<uint8_t> out;
        EXPECT_EQ(w.to_bytes(out).rule, rule::kElementSize);
    }
    {
        Writer w;
        w.add_section(fourcc('A', 'B', 'C', 'D'), 2, 4, 4, bytes);
        std::vector<uint8_t> out;
        EXPECT_EQ(w.to_bytes(out).rule, rule::kSectionFlags);
    }
}

TEST(Writer, WriteFailsCleanlyIntoMissingDirectory) {
    Writer w;
    const SceneData scene = make_synthetic_scene({});
    add_scene_sections(w, scene);
    const Result r = w.write_file(test::temp_dir() + "/no/such/dir/x.cwbvh");
    EXPECT_EQ(r.status, Status::kIoError);
    EXPECT_NE(r.message.find("no/such/dir"), std::string::npos) << r.message;
}

TEST(Synthetic, VariantsAreValid) {
    for (uint32_t n : {0u, 1u, 2u, 3u, 4u, 24u, 25u, 26u, 100u, 1000u}) {
        for (int flags = 0; flags < 2; ++flags) {
            SyntheticOptions o;
            o.triangles = n;
            o.bvh2 = o.source_geometry = o.build_info = flags == 0;
            const Result r = validate(test::file_bytes(make_synthetic_scene(o)));
            EXPECT_TRUE(r.ok()) << n << " triangles: " << r.describe();
        }
    }
}

}  // namespace
}  // namespace cwbvh
