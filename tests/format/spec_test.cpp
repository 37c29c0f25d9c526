// spec/cwbvh-format.md and the code agree: the rule table lists exactly the
// rule IDs of status.h, and the header/entry tables give the struct offsets.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"

namespace cwbvh {
namespace {

std::string spec_text() {
    std::ifstream in(std::string(CWBVH_SOURCE_DIR) + "/spec/cwbvh-format.md");
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

TEST(Spec, RuleTableMatchesCode) {
    const std::string spec = spec_text();
    ASSERT_FALSE(spec.empty());
    std::set<uint32_t> in_spec;
    const std::regex row(R"(\n\| (\d{4}) \|)");
    for (auto it = std::sregex_iterator(spec.begin(), spec.end(), row); it != std::sregex_iterator(); ++it)
        in_spec.insert(uint32_t(std::stoul((*it)[1])));
    const std::set<uint32_t> in_code(std::begin(rule::kAll), std::end(rule::kAll));
    EXPECT_EQ(in_spec, in_code);
}

TEST(Spec, LayoutTablesMatchStructs) {
    const std::string spec = spec_text();
    auto has_row = [&](size_t offset, size_t size, const char* field) {
        const std::string row = "| " + std::to_string(offset) + " | " + std::to_string(size) + " |";
        const size_t at = spec.find(row + " ");
        bool found = false;
        for (size_t pos = at; pos != std::string::npos; pos = spec.find(row + " ", pos + 1)) {
            const size_t eol = spec.find('\n', pos);
            if (spec.substr(pos, eol - pos).find(field) != std::string::npos) found = true;
        }
        return found;
    };
#define CWBVH_ROW(T, f, name) EXPECT_TRUE(has_row(offsetof(T, f), sizeof(T::f), name)) << #T "::" #f
    CWBVH_ROW(FileHeader, version_major, "`version_major`");
    CWBVH_ROW(FileHeader, section_table_offset, "`section_table_offset`");
    CWBVH_ROW(FileHeader, meta_checksum, "`meta_checksum`");
    CWBVH_ROW(SectionEntry, element_count, "`element_count`");
    CWBVH_ROW(SectionEntry, checksum, "`checksum`");
    CWBVH_ROW(CwbvhNode, imask, "`imask`");
    CWBVH_ROW(CwbvhNode, child_base, "`child_base`");
    CWBVH_ROW(CwbvhNode, meta, "`meta`");
    CWBVH_ROW(TriangleRecord, prim, "`prim`");
    CWBVH_ROW(TriangleRecord, v1, "`v1`");
    CWBVH_ROW(TriangleRecord, v2, "`v2`");
    CWBVH_ROW(SourceRange, first, "`first`");
    CWBVH_ROW(SourceRange, count, "`count`");
    CWBVH_ROW(SourceRange, primitive, "`primitive`");
    CWBVH_ROW(SourceRange, first_triangle, "`first_triangle`");
    CWBVH_ROW(BuildInfo, wide_nodes, "`wide_nodes`");
    CWBVH_ROW(BuildInfo, sah_binary, "`sah_binary`");
    CWBVH_ROW(BuildInfo, reserved, "`reserved`");
    CWBVH_ROW(Bvh2Node, child, "`child[2]`");
    CWBVH_ROW(Bvh2Node, leaf_count, "`leaf_count[2]`");
    // Format 1.2 (spec 3.9, 3.10): every field of the two-level records.
    CWBVH_ROW(MeshRecord, node_first, "`node_first`");
    CWBVH_ROW(MeshRecord, node_count, "`node_count`");
    CWBVH_ROW(MeshRecord, tri_first, "`tri_first`");
    CWBVH_ROW(MeshRecord, tri_count, "`tri_count`");
    CWBVH_ROW(MeshRecord, prim_first, "`prim_first`");
    CWBVH_ROW(MeshRecord, prim_count, "`prim_count`");
    CWBVH_ROW(MeshRecord, lo, "`lo`");
    CWBVH_ROW(MeshRecord, hi, "`hi`");
    CWBVH_ROW(MeshRecord, source_mesh, "`source_mesh`");
    CWBVH_ROW(MeshRecord, reserved, "`reserved`");
    CWBVH_ROW(InstanceRecord, object_to_world, "`object_to_world`");
    CWBVH_ROW(InstanceRecord, world_to_object, "`world_to_object`");
    CWBVH_ROW(InstanceRecord, mesh, "`mesh`");
    CWBVH_ROW(InstanceRecord, source_node, "`source_node`");
    CWBVH_ROW(InstanceRecord, world_lo, "`world_lo`");
    CWBVH_ROW(InstanceRecord, world_hi, "`world_hi`");
#undef CWBVH_ROW
    EXPECT_TRUE(has_row(offsetof(CwbvhNode, q_hi) + 16, 8, "`q_hi[2]`"));
}

}  // namespace
}  // namespace cwbvh
