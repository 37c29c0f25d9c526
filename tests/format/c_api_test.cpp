// The C API: handles, per-handle errors, accessors.
#include <gtest/gtest.h>

#include "cwbvh/cwbvh.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

TEST(CApi, OpensAndReadsSections) {
    const SceneData scene = make_synthetic_scene({});
    const std::string path = test::write_temp("c_api.cwbvh", test::file_bytes(scene));
    cwbvh_file* f = nullptr;
    ASSERT_EQ(cwbvh_open(path.c_str(), nullptr, &f), CWBVH_OK);
    ASSERT_NE(f, nullptr);
    EXPECT_STREQ(cwbvh_error_message(f), "");
    uint64_t n = 0;
    EXPECT_NE(cwbvh_nodes(f, &n), nullptr);
    EXPECT_EQ(n, scene.nodes.size());
    EXPECT_NE(cwbvh_triangles(f, &n), nullptr);
    EXPECT_EQ(n, scene.triangles.size());
    EXPECT_NE(cwbvh_source_ranges(f, &n), nullptr);
    EXPECT_EQ(n, scene.source_ranges.size());
    cwbvh_source_ref ref{};
    ASSERT_EQ(cwbvh_source_of(f, 9, &ref), CWBVH_OK);  // synthetic: primitives of 8 triangles
    EXPECT_EQ(ref.input, 0u);
    EXPECT_EQ(ref.primitive, 1u);
    EXPECT_EQ(ref.triangle, 1u);
    EXPECT_EQ(cwbvh_source_of(f, uint32_t(scene.triangles.size()), &ref), CWBVH_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(cwbvh_source_of(f, 0, nullptr), CWBVH_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(cwbvh_source_of(nullptr, 0, &ref), CWBVH_ERROR_INVALID_ARGUMENT);
    ASSERT_NE(cwbvh_bounds(f), nullptr);
    EXPECT_EQ(cwbvh_bounds(f)[3], scene.bounds.hi[0]);
    EXPECT_NE(cwbvh_build_info(f), nullptr);
    EXPECT_NE(cwbvh_bvh2(f, &n), nullptr);
    EXPECT_EQ(n, scene.bvh2.size());
    EXPECT_NE(cwbvh_vertices(f, &n), nullptr);
    EXPECT_EQ(n * 3, scene.vertices.size());
    EXPECT_NE(cwbvh_indices(f, &n), nullptr);
    EXPECT_EQ(n * 3, scene.indices.size());
    EXPECT_NE(cwbvh_source_names(f, &n), nullptr);
    EXPECT_EQ(n, scene.source_names.size());
    EXPECT_EQ(cwbvh_section(f, kSectionNodes, &n), cwbvh_nodes(f, nullptr));
    EXPECT_EQ(n, scene.nodes.size() * 80);
    cwbvh_close(f);
}

TEST(CApi, ErrorsArePerHandle) {
    const std::string missing = test::temp_dir() + "/missing.cwbvh";
    std::vector<uint8_t> bad = test::synthetic_file();
    bad[test::entry(bad, test::find_entry(bad, kSectionTriangles)).offset] ^= 1;  // low mantissa bit
    const std::string corrupt = test::write_temp("c_api_bad.cwbvh", bad);
    cwbvh_file* a = nullptr;
    cwbvh_file* b = nullptr;
    EXPECT_EQ(cwbvh_open(missing.c_str(), nullptr, &a), CWBVH_ERROR_IO);
    EXPECT_EQ(cwbvh_open(corrupt.c_str(), nullptr, &b), CWBVH_ERROR_CHECKSUM);
    ASSERT_NE(a, nullptr);
    ASSERT_NE(b, nullptr);
    EXPECT_NE(std::string(cwbvh_error_message(a)).find("missing.cwbvh"), std::string::npos);
    EXPECT_NE(std::string(cwbvh_error_message(b)).find("checksum"), std::string::npos) << cwbvh_error_message(b);
    EXPECT_EQ(cwbvh_error_rule(a), rule::kOpenFailed);
    EXPECT_EQ(cwbvh_status_of(b), CWBVH_ERROR_CHECKSUM);
    uint64_t n = 7;
    EXPECT_EQ(cwbvh_nodes(b, &n), nullptr);
    EXPECT_EQ(n, 0u);
    cwbvh_close(a);
    cwbvh_close(b);
    // Without payload checksums the damaged (non-structural) byte passes.
    cwbvh_open_options o;
    cwbvh_open_options_init(&o);
    o.verify_checksums = 0;
    cwbvh_file* c = nullptr;
    EXPECT_EQ(cwbvh_open(corrupt.c_str(), &o, &c), CWBVH_OK) << cwbvh_error_message(c);
    cwbvh_close(c);
}

TEST(CApi, InvalidArguments) {
    cwbvh_file* f = nullptr;
    EXPECT_EQ(cwbvh_open(nullptr, nullptr, &f), CWBVH_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(f, nullptr);
    EXPECT_EQ(cwbvh_open("x", nullptr, nullptr), CWBVH_ERROR_INVALID_ARGUMENT);
    cwbvh_open_options o{};
    EXPECT_EQ(cwbvh_open("x", &o, &f), CWBVH_ERROR_INVALID_ARGUMENT);  // struct_size 0
    EXPECT_EQ(cwbvh_nodes(nullptr, nullptr), nullptr);
    EXPECT_NE(cwbvh_error_message(nullptr), nullptr);
    EXPECT_STREQ(cwbvh_status_string(CWBVH_ERROR_CORRUPT), "corrupt");
    EXPECT_STREQ(cwbvh_status_string(CWBVH_ERROR_OUT_OF_MEMORY), "out of memory");  // was "unknown status"
    cwbvh_open_options_init(&o);
    o.reserved = 7;  // the header says 0; it was accepted
    EXPECT_EQ(cwbvh_open("x", &o, &f), CWBVH_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(f, nullptr);
    cwbvh_close(nullptr);
}

}  // namespace
}  // namespace cwbvh
