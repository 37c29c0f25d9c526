// spec/vectors/: the committed files equal what vectors.cpp makes, and they
// decode exactly as their .json files state. CWBVH_UPDATE_VECTORS=1 rewrites
// them (and the fuzz seed corpus) instead.
#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "cwbvh/format/describe.h"
#include "cwbvh/format/node_decode.h"
#include "format/test_util.h"
#include "format/vectors.h"

namespace cwbvh {
namespace {

const std::string kDir = std::string(CWBVH_SOURCE_DIR) + "/spec/vectors/";
const std::string kCorpus = std::string(CWBVH_SOURCE_DIR) + "/tests/fuzz/corpus/";

std::string read_text(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

std::string json_escape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '"' || c == '\\') o += '\\';
        o += c;
    }
    return o;
}

/// What the .json of a vector states.
std::string expected_json(const std::vector<uint8_t>& bytes) {
    FileLayout layout;
    const Result r = validate(bytes, {}, &layout);
    if (r.ok()) return describe_json(layout, true);
    return "{\n  \"valid\": false,\n  \"status\": \"" + std::string(status_name(r.status)) +
           "\",\n  \"rule\": " + std::to_string(r.rule) + ",\n  \"message\": \"" + json_escape(r.message) + "\"\n}\n";
}

bool updating() { return std::getenv("CWBVH_UPDATE_VECTORS") != nullptr; }

void write_bytes(const std::string& path, const std::string& data) {
    std::ofstream(path, std::ios::binary).write(data.data(), std::streamsize(data.size()));
}

TEST(Vectors, CommittedFilesMatchAndDecodeAsStated) {
    for (const test::Vector& v : test::make_vectors()) {
        SCOPED_TRACE(v.name);
        const std::string bin = kDir + v.name + ".cwbvh", json = kDir + v.name + ".json";
        const std::string bytes(v.bytes.begin(), v.bytes.end());
        if (updating()) {
            write_bytes(bin, bytes);
            write_bytes(json, expected_json(v.bytes));
            write_bytes(kCorpus + v.name + ".cwbvh", bytes);
            continue;
        }
        EXPECT_EQ(read_text(bin), bytes) << "regenerate with CWBVH_UPDATE_VECTORS=1 if the change is intended";
        const std::string committed = read_text(bin);
        EXPECT_EQ(expected_json(std::vector<uint8_t>(committed.begin(), committed.end())), read_text(json));
    }
}

TEST(Vectors, SingleTriangleDecodesAsTheSpecSays) {
    const std::string bytes = read_text(kDir + "single_triangle.cwbvh");
    const std::vector<uint8_t> f(bytes.begin(), bytes.end());
    FileLayout l;
    ASSERT_TRUE(validate(f, {}, &l).ok());
    ASSERT_EQ(l.find(kSectionNodes)->element_count, 1u);
    CwbvhNode root;
    std::memcpy(&root, l.payload(*l.find(kSectionNodes)).data(), sizeof root);
    EXPECT_EQ(root.meta[0], 0x20);  // leaf, unary count 0b001, offset 0
    EXPECT_EQ(root.imask, 0);
    EXPECT_EQ(decode_plane(root.p[0], root.e[0], root.q_hi[0][0]), 1.0f);
    EXPECT_EQ(decode_plane(root.p[1], root.e[1], root.q_hi[1][0]), 1.0f);
    EXPECT_EQ(decode_plane(root.p[2], root.e[2], root.q_hi[2][0]), 0.0f);
    EXPECT_EQ(exponent_scale(120), 1.0f / 128.0f);
    TriangleRecord t;
    std::memcpy(&t, l.payload(*l.find(kSectionTriangles)).data(), sizeof t);
    EXPECT_EQ(t.v1[0], 1.0f);
    EXPECT_EQ(t.prim, 0u);
    // First bytes as the spec's hex dump shows them.
    const uint8_t head[16] = {0xAB, 'C', 'W', 'B', 'V', 'H', 0xBB, 0x0D, 0x0A, 0x1A, 0x0A, 0x00, 1, 0, 0, 0};
    EXPECT_EQ(std::memcmp(f.data(), head, 16), 0);
}

TEST(Vectors, InvalidOnesFailWithTheirRule) {
    for (const auto& [name, rule_id] : {std::pair<const char*, uint32_t>{"invalid_5105_child_order", 5105},
                                       {"invalid_2003_major_version", 2003},
                                       {"invalid_3002_truncated", 3002},
                                       {"invalid_5608_leaf_range", 5608}}) {
        const std::string bytes = read_text(kDir + name + ".cwbvh");
        EXPECT_EQ(validate(std::vector<uint8_t>(bytes.begin(), bytes.end())).rule, rule_id) << name;
    }
}

TEST(Vectors, LeafRangesIsFormat11WithABv2lSection) {
    const std::string bytes = read_text(kDir + "leaf_ranges.cwbvh");
    const std::vector<uint8_t> f(bytes.begin(), bytes.end());
    FileLayout l;
    ASSERT_TRUE(validate(f, {}, &l).ok());
    EXPECT_EQ(l.header.version_minor, 1u);
    ASSERT_NE(l.find(kSectionBvh2Leaves), nullptr);
    EXPECT_EQ(l.find(kSectionBvh2), nullptr);
    // The leaves tile TRIS: every record in exactly one leaf range.
    const SectionEntry& e = *l.find(kSectionBvh2Leaves);
    std::vector<int> covered(l.find(kSectionTriangles)->element_count, 0);
    for (uint64_t i = 0; i < e.element_count; ++i) {
        Bvh2Node n;
        std::memcpy(&n, l.payload(e).data() + i * sizeof n, sizeof n);
        for (int c = 0; c < 2; ++c)
            for (uint32_t k = 0; n.child[c] < 0 && k < n.leaf_count[c]; ++k) ++covered.at(uint32_t(~n.child[c]) + k);
    }
    for (int c : covered) EXPECT_EQ(c, 1);
}

/// The verdict a corpus file's name states, as in spec/vectors: "invalid_<rule>_..." breaks
/// that rule; any other name is a valid file. 0: valid.
uint32_t stated_rule(const std::string& stem) {
    if (stem.rfind("invalid_", 0) != 0) return 0;
    return uint32_t(std::strtoul(stem.c_str() + 8, nullptr, 10));
}

TEST(FuzzCorpus, EveryFileGetsTheVerdictItsNameStates) {
    size_t files = 0, invalid = 0;
    for (const auto& e : std::filesystem::directory_iterator(kCorpus)) {
        SCOPED_TRACE(e.path().filename().string());
        const std::string bytes = read_text(e.path().string());
        std::unique_ptr<uint8_t[]> buf(new uint8_t[bytes.size() + 1]);
        std::memcpy(buf.get(), bytes.data(), bytes.size());
        const Result r = validate({buf.get(), bytes.size()});
        const uint32_t rule = stated_rule(e.path().stem().string());
        if (rule == 0) {
            EXPECT_TRUE(r.ok()) << r.describe();
        } else {
            ++invalid;
            EXPECT_FALSE(r.ok()) << "expected rule " << rule;
            EXPECT_EQ(r.rule, rule) << r.describe();
            EXPECT_FALSE(r.message.empty());
        }
        ++files;
    }
    EXPECT_GE(files, 3u);
    EXPECT_GT(invalid, 0u);
    EXPECT_LT(invalid, files);
}

}  // namespace
}  // namespace cwbvh
