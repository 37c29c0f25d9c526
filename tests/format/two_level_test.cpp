// Format 1.2, two-level scenes (spec 3.9-3.11): a valid file passes every rule
// and deep check, each new rule fails on its own hostile mutation, the loader and
// the C API hand out the sections, and single-level files are unchanged.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "cwbvh/cwbvh.h"
#include "cwbvh/format/deep_check.h"
#include "cwbvh/format/describe.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/sections.h"
#include "cwbvh/format/transform_host.h"
#include "cwbvh/format/tree_depth.h"
#include "cwbvh/loader/loader.h"
#include "format/test_util.h"
#include "format/two_level_scene.h"

namespace cwbvh {
namespace {

using test::edit_element;

template <class T>
std::vector<T> section_copy(const std::vector<uint8_t>& f, const FileLayout& l, uint32_t type) {
    const SectionEntry* e = l.find(type);
    std::vector<T> v(e ? e->element_count : 0);
    if (e && e->size) std::memcpy(v.data(), f.data() + e->offset, e->size);
    return v;
}

/// validate(), then the deep checks D1-D4 (per mesh) and D7, as `cwbvh validate --deep`.
Result deep(const std::vector<uint8_t>& f, DeepCheckStats* stats = nullptr) {
    FileLayout l;
    if (Result r = validate(f, {}, &l); !r.ok()) return r;
    const auto nodes = section_copy<CwbvhNode>(f, l, kSectionNodes);
    const auto tris = section_copy<TriangleRecord>(f, l, kSectionTriangles);
    const auto pmap = section_copy<SourceRange>(f, l, kSectionSourceMap);
    const auto meshes = section_copy<MeshRecord>(f, l, kSectionMeshes);
    const auto inst = section_copy<InstanceRecord>(f, l, kSectionInstances);
    const auto top = section_copy<CwbvhNode>(f, l, kSectionTopNodes);
    const auto bounds = section_copy<SceneBounds>(f, l, kSectionBounds);
    const uint64_t stored = pmap.empty() ? 0 : uint64_t(pmap.back().first) + pmap.back().count;
    DeepCheckStats local;
    DeepCheckStats& st = stats ? *stats : local;
    if (Result r = deep_check(nodes, tris, stored, &st); !r.ok()) return r;
    return deep_check_two_level(tris, TwoLevelView{meshes, inst, top, bounds.data()}, &st);
}

std::vector<uint8_t> standard_file() { return test::file_bytes(test::standard_two_level()); }

TEST(TwoLevel, StandardSceneIsValidAndDeepChecked) {
    const SceneData s = test::standard_two_level();
    ASSERT_EQ(s.meshes.size(), 2u);
    ASSERT_EQ(s.instances.size(), 5u);
    ASSERT_EQ(s.top_nodes.size(), 2u);  // root + one internal child: two TLAS levels
    const std::vector<uint8_t> f = test::file_bytes(s);
    DeepCheckStats st;
    const Result r = deep(f, &st);
    ASSERT_TRUE(r.ok()) << r.describe();
    EXPECT_EQ(st.instances, 5u);
    EXPECT_EQ(st.unsplit_triangles + st.split_triangles, 40u);  // D2/D3 in each mesh, to its own root
    EXPECT_EQ(test::header_of(f).version_minor, 2);
    for (const uint32_t type : {kSectionMeshes, kSectionInstances, kSectionTopNodes})
        EXPECT_EQ(test::entry(f, test::find_entry(f, type)).flags, uint32_t(kSectionRequired)) << section_name(type);
    // The one section order (scene_data.cpp): NODE TRIS PMAP BNDS MESH INST TLAS.
    const uint32_t order[] = {kSectionNodes, kSectionTriangles, kSectionSourceMap, kSectionBounds,
                              kSectionMeshes, kSectionInstances, kSectionTopNodes};
    for (uint32_t i = 0; i < 7; ++i) EXPECT_EQ(test::entry(f, i).type, order[i]) << i;
}

TEST(TwoLevel, SingleLevelFilesAreUnchanged) {
    // Same bytes as a 1.1 writer: stamped 0 (1 with BV2L), no two-level section. The committed
    // vectors (written before format 1.2) are compared byte for byte by Vectors.*.
    SyntheticOptions o;
    const std::vector<uint8_t> f = test::file_bytes(make_synthetic_scene(o));
    EXPECT_EQ(test::header_of(f).version_minor, 0);
    o.bvh2_leaf_ranges = true;
    EXPECT_EQ(test::header_of(test::file_bytes(make_synthetic_scene(o))).version_minor, 1);
    FileLayout l;
    ASSERT_TRUE(validate(f, {}, &l).ok());
    EXPECT_EQ(l.find(kSectionMeshes), nullptr);
}

TEST(TwoLevel, AReaderWithoutTheTypesRejectsByTheRequiredBit) {
    // What a 1.1 reader sees: three section types it does not know, flagged required. Renaming
    // MESH to a type this reader does not know either shows the same path: rule 4009.
    std::vector<uint8_t> f = standard_file();
    const uint32_t i = test::find_entry(f, kSectionMeshes);
    SectionEntry e = test::entry(f, i);
    e.type = fourcc('M', 'E', 'S', 'Z');
    test::set_entry(f, i, e);
    test::reseal(f);
    EXPECT_RULE(test::check(f), rule::kUnknownRequiredSection);
}

// ---- loader and C API ----

TEST(TwoLevel, LoaderHandsOutTheSections) {
    const SceneData s = test::standard_two_level();
    const std::string path = test::write_temp("two_level.cwbvh", test::file_bytes(s));
    auto f = File::open(path);
    ASSERT_TRUE(f.ok()) << f.error().describe();
    EXPECT_TRUE(f->is_two_level());
    ASSERT_EQ(f->meshes().size(), 2u);
    ASSERT_EQ(f->instances().size(), 5u);
    ASSERT_EQ(f->top_nodes().size(), 2u);
    EXPECT_EQ(f->meshes()[1].node_first, 3u);
    EXPECT_EQ(std::memcmp(f->instances().data(), s.instances.data(), 5 * sizeof(InstanceRecord)), 0);
    EXPECT_EQ(f->stored_triangle_count(), 40u);
    EXPECT_EQ(f->instanced_triangle_count(), 30u + 10 + 30 + 10 + 30);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(f->instances().data()) % 64, 0u);

    // NODE without the top level would trace mesh 0 alone: refused like an unknown required section.
    OpenOptions o;
    o.sections = kMaskNodes | kMaskTriangles;
    auto partial = File::open(path, o);
    ASSERT_FALSE(partial.ok());
    EXPECT_EQ(partial.error().rule, rule::kUnknownRequiredSection) << partial.error().describe();
    o.sections |= kMaskTwoLevel;
    auto traversal = File::open(path, o);
    ASSERT_TRUE(traversal.ok()) << traversal.error().describe();
    EXPECT_EQ(traversal->top_nodes().size(), 2u);
    EXPECT_TRUE(traversal->source_ranges().empty());

    // A single-level file: no two-level sections, nothing refused.
    auto single = File::open(test::write_temp("single.cwbvh", test::synthetic_file()), o);
    ASSERT_TRUE(single.ok());
    EXPECT_FALSE(single->is_two_level());
    EXPECT_TRUE(single->meshes().empty());
    EXPECT_EQ(single->instanced_triangle_count(), 0u);
}

TEST(TwoLevel, CApi) {
    const std::string path = test::write_temp("two_level_c.cwbvh", standard_file());
    cwbvh_file* f = nullptr;
    ASSERT_EQ(cwbvh_open(path.c_str(), nullptr, &f), CWBVH_OK) << cwbvh_error_message(f);
    EXPECT_EQ(cwbvh_is_two_level(f), 1);
    uint64_t n = 0;
    EXPECT_NE(cwbvh_meshes(f, &n), nullptr);
    EXPECT_EQ(n, 2u);
    EXPECT_NE(cwbvh_instances(f, &n), nullptr);
    EXPECT_EQ(n, 5u);
    EXPECT_NE(cwbvh_top_nodes(f, &n), nullptr);
    EXPECT_EQ(n, 2u);
    cwbvh_close(f);

    // A caller of the 1.1 API selecting NODE and TRIS only (or all nine 1.1 bits) is refused.
    cwbvh_open_options o;
    cwbvh_open_options_init(&o);
    o.sections = CWBVH_SECTION_NODES | CWBVH_SECTION_TRIANGLES;
    EXPECT_EQ(cwbvh_open(path.c_str(), &o, &f), CWBVH_ERROR_UNSUPPORTED);
    EXPECT_EQ(cwbvh_error_rule(f), rule::kUnknownRequiredSection);
    EXPECT_EQ(cwbvh_is_two_level(f), 0);
    EXPECT_EQ(cwbvh_meshes(f, &n), nullptr);
    cwbvh_close(f);
    o.sections = (1u << 9) - 1u;
    EXPECT_EQ(cwbvh_open(path.c_str(), &o, &f), CWBVH_ERROR_UNSUPPORTED);
    cwbvh_close(f);
    o.sections |= CWBVH_SECTION_TWO_LEVEL;
    EXPECT_EQ(cwbvh_open(path.c_str(), &o, &f), CWBVH_OK);
    cwbvh_close(f);
}

TEST(TwoLevel, DescribeCountsDistinctAndInstancedTriangles) {
    FileLayout l;
    const std::vector<uint8_t> f = standard_file();
    ASSERT_TRUE(validate(f, {}, &l).ok());
    const std::string text = describe_text(l);
    EXPECT_NE(text.find("two-level: 2 meshes, 5 instances, 2 top-level nodes; triangles 40 distinct, 110 instanced"),
              std::string::npos)
        << text;
    const std::string json = describe_json(l);
    EXPECT_NE(json.find("\"two_level\": {\"meshes\": 2, \"instances\": 5, \"top_nodes\": 2, "
                        "\"distinct_triangles\": 40, \"instanced_triangles\": 110}"),
              std::string::npos)
        << json;
}

TEST(TwoLevel, CliInfoAndDeepValidate) {
    const std::string path = test::write_temp("two_level_cli.cwbvh", standard_file());
    const test::ToolRun info = test::run_cwbvh("info " + path);
    EXPECT_EQ(info.code, 0) << info.out;
    EXPECT_NE(info.out.find("40 distinct, 110 instanced"), std::string::npos) << info.out;
    const test::ToolRun json = test::run_cwbvh("info --json " + path);
    EXPECT_NE(json.out.find("\"instanced_triangles\": 110"), std::string::npos) << json.out;
    const test::ToolRun v = test::run_cwbvh("validate --deep " + path);
    EXPECT_EQ(v.code, 0) << v.out;
    EXPECT_NE(v.out.find("5 instances inside their world and top-level boxes"), std::string::npos) << v.out;

    std::vector<uint8_t> bad = standard_file();
    edit_element<InstanceRecord>(bad, kSectionInstances, 2, [](InstanceRecord& r) { r.mesh = 7; });
    const test::ToolRun b = test::run_cwbvh("validate " + test::write_temp("two_level_bad.cwbvh", bad));
    EXPECT_EQ(b.code, 1);
    EXPECT_NE(b.out.find("[rule 6024]"), std::string::npos) << b.out;
    EXPECT_EQ(test::count_lines(b.out), 1u) << b.out;
}

// ---- structure: 6001, 4011 ----

TEST(TwoLevel, Rule6001AllThreeOrNone) {
    const SceneData s = test::standard_two_level();
    Writer w;
    // add_scene_sections writes all three when any is present; write MESH alone by hand.
    SceneSections single = s.sections();
    single.meshes = {};
    single.instances = {};
    single.top_nodes = {};
    add_scene_sections(w, single);
    w.add_section(kSectionMeshes, kSectionRequired, sizeof(MeshRecord), s.meshes.size(),
                  {reinterpret_cast<const uint8_t*>(s.meshes.data()), s.meshes.size() * sizeof(MeshRecord)});
    std::vector<uint8_t> f;
    ASSERT_TRUE(w.to_bytes(f).ok());
    EXPECT_RULE(test::check(f), rule::kTwoLevelSections);

    SceneData with_bvh2 = s;
    with_bvh2.bvh2.push_back(Bvh2Node{0, 1, 0, 1, 0, 1, 0, 1, 0, 0, 0, 0, {~0, ~0}, {0, 0}});
    EXPECT_RULE(test::check(test::file_bytes(with_bvh2)), rule::kTwoLevelSections);

    SceneData empty_inst = s;
    empty_inst.instances.clear();  // MESH and TLAS present, INST written empty
    EXPECT_RULE(test::check(test::file_bytes(empty_inst)), rule::kElementCount);
}

// ---- MESH: 6002-6007 ----

TEST(TwoLevel, MeshRangeRules) {
    auto mutate = [](auto edit) {
        std::vector<uint8_t> f = standard_file();
        edit_element<MeshRecord>(f, kSectionMeshes, 1, edit);
        return test::check(f);
    };
    EXPECT_RULE(mutate([](MeshRecord& m) { m.node_first += 1; }), rule::kMeshNodeRange);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.node_count = 0; }), rule::kMeshNodeRange);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.node_count += 1; }), rule::kMeshNodeRange);  // past NODE's end
    EXPECT_RULE(mutate([](MeshRecord& m) { m.tri_first -= 1; }), rule::kMeshTriRange);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.tri_count -= 1; }), rule::kMeshTriRange);  // TRIS not covered
    EXPECT_RULE(mutate([](MeshRecord& m) { m.prim_first += 1; }), rule::kMeshPrimRange);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.prim_count = 0; }), rule::kMeshPrimRange);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.lo[1] = NAN; }), rule::kMeshBounds);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.lo[2] = m.hi[2] + 1; }), rule::kMeshBounds);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.reserved[2] = 1; }), rule::kMeshReserved);
    // Counts from the file never size anything: a mesh claiming 2^32-1 nodes fails its rule at once.
    EXPECT_RULE(mutate([](MeshRecord& m) { m.node_count = 0xFFFFFFFFu; }), rule::kMeshNodeRange);
    EXPECT_RULE(mutate([](MeshRecord& m) { m.prim_count = 0xFFFFFFFFu; }), rule::kMeshPrimRange);
    // A mesh 0 record naming a stored triangle of mesh 1 (still below the PMAP total: 5201 holds).
    std::vector<uint8_t> f = standard_file();
    edit_element<TriangleRecord>(f, kSectionTriangles, 4, [](TriangleRecord& t) { t.prim = 35; });
    EXPECT_RULE(test::check(f), rule::kMeshPrim);
}

TEST(TwoLevel, NodeRulesApplyPerMesh) {
    // Mesh 0 = NODE 0..2, mesh 1 = NODE 3 (TRIS 30..39).
    std::vector<uint8_t> f = standard_file();
    edit_element<CwbvhNode>(f, kSectionNodes, 0, [](CwbvhNode& n) { n.child_base = 2; });  // children 2, 3
    const Result r = test::check(f);
    EXPECT_RULE(r, rule::kNodeChildRange);
    EXPECT_NE(r.message.find("mesh 0"), std::string::npos) << r.message;

    f = standard_file();
    edit_element<CwbvhNode>(f, kSectionNodes, 3, [](CwbvhNode& n) { n.tri_base = 0; });  // mesh 0's records
    EXPECT_RULE(test::check(f), rule::kNodeLeafRange);

    // Each mesh root may be parentless; any other parentless node is not.
    f = standard_file();
    edit_element<CwbvhNode>(f, kSectionNodes, 0, [](CwbvhNode& n) {
        const int last = 31 - __builtin_clz(n.imask);  // drop the last internal child: node 2 loses its parent
        n.imask = uint8_t(n.imask & ~(1u << last));
        n.meta[last] = 0;
        for (int a = 0; a < 3; ++a) n.q_lo[a][last] = n.q_hi[a][last] = 0;
    });
    EXPECT_RULE(test::check(f), rule::kNodeParents);
}

// ---- INST: 6021-6025 ----

TEST(TwoLevel, InstanceRules) {
    auto mutate = [](uint64_t i, auto edit) {
        std::vector<uint8_t> f = standard_file();
        edit_element<InstanceRecord>(f, kSectionInstances, i, edit);
        return test::check(f);
    };
    EXPECT_RULE(mutate(1, [](InstanceRecord& r) { r.object_to_world[1][3] = INFINITY; }), rule::kInstNonFinite);
    EXPECT_RULE(mutate(1, [](InstanceRecord& r) { r.world_to_object[2][0] = NAN; }), rule::kInstNonFinite);
    EXPECT_RULE(mutate(0, [](InstanceRecord& r) { r.object_to_world[2][2] = 0; }), rule::kInstCondition);  // singular
    EXPECT_RULE(mutate(0, [](InstanceRecord& r) { r.object_to_world[2][2] = 1e-7f; }), rule::kInstCondition);
    EXPECT_RULE(mutate(1, [](InstanceRecord& r) { r.world_to_object[0][3] += 0.01f; }), rule::kInstInverse);
    // Instance 3 is a mirrored 90-degree rotation scaled by 2: W[0][1] = -0.5 (W[1][1] is a
    // rounding residue of cos 90, far below the 2^-20 * max|X| the tolerance allows).
    EXPECT_RULE(mutate(3, [](InstanceRecord& r) { r.world_to_object[0][1] *= 1.001f; }), rule::kInstInverse);
    EXPECT_TRUE(mutate(3, [](InstanceRecord& r) { r.world_to_object[1][1] *= 1.001f; }).ok());
    EXPECT_RULE(mutate(4, [](InstanceRecord& r) { r.mesh = 2; }), rule::kInstMesh);
    EXPECT_RULE(mutate(2, [](InstanceRecord& r) { r.world_hi[0] = INFINITY; }), rule::kInstWorldBox);
    EXPECT_RULE(mutate(2, [](InstanceRecord& r) { r.world_lo[1] = r.world_hi[1] + 1; }), rule::kInstWorldBox);
    // The inverse's tolerance accepts another writer's rounding: one ulp off RN(X) is valid.
    const Result ulp = mutate(3, [](InstanceRecord& r) {
        r.world_to_object[0][1] = std::nextafter(r.world_to_object[0][1], INFINITY);
        r.world_to_object[1][3] = std::nextafter(r.world_to_object[1][3], -INFINITY);
    });
    EXPECT_TRUE(ulp.ok()) << ulp.describe();
    // ... but a translation that is exactly 0 without cancellation (t_z = 0, no z terms) must be 0.
    EXPECT_RULE(mutate(3, [](InstanceRecord& r) { r.world_to_object[2][3] = 1e-30f; }), rule::kInstInverse);
}

// ---- TLAS: 61xx (the NODE rules + 1000) ----

TEST(TwoLevel, TopLevelRules) {
    auto mutate = [](uint64_t i, auto edit) {
        std::vector<uint8_t> f = standard_file();
        edit_element<CwbvhNode>(f, kSectionTopNodes, i, edit);
        return test::check(f);
    };
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.e[1] = 0; }), rule::kTlasExponent);
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.meta[1] = 0x39 + 1; }), rule::kTlasMeta);
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.imask = 0x01 | n.imask; }), rule::kTlasImask);
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.child_base = 2; }), rule::kTlasChildRange);
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.child_base = 0; }), rule::kTlasChildOrder);
    EXPECT_RULE(mutate(1, [](CwbvhNode& n) { n.tri_base = 3; }), rule::kTlasLeafRange);  // 3 + 3 > 5 instances
    EXPECT_RULE(mutate(1, [](CwbvhNode& n) { n.tri_base = 1; }), rule::kTlasInstanceUse);  // instance 1 twice
    EXPECT_RULE(mutate(1, [](CwbvhNode& n) { n.meta[1] = make_meta_leaf(1, 0); }), rule::kTlasLeafLayout);
    EXPECT_RULE(mutate(1, [](CwbvhNode& n) {
                    n.q_lo[0][0] = 200;
                    n.q_hi[0][0] = 100;
                }),
                rule::kTlasPlaneOrder);
    EXPECT_RULE(mutate(1, [](CwbvhNode& n) { n.q_hi[2][7] = 1; }), rule::kTlasEmptySlot);
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.p[0] = NAN; }), rule::kTlasNonFinite);
    // A TLAS record no leaf references: drop the root's leaf count from 2 to 1.
    EXPECT_RULE(mutate(0, [](CwbvhNode& n) { n.meta[0] = make_meta_leaf(1, 0); }), rule::kTlasInstanceUse);
    // A non-root TLAS node without a used slot.
    EXPECT_RULE(mutate(1, [](CwbvhNode& n) {
                    std::memset(n.meta, 0, sizeof n.meta);
                    std::memset(n.q_lo, 0, sizeof n.q_lo);
                    std::memset(n.q_hi, 0, sizeof n.q_hi);
                }),
                rule::kTlasEmpty);
}

/// A mesh that is a chain of `levels` unit nodes (each with one leaf triangle).
SceneData chain_mesh(uint32_t levels) {
    SceneData s;
    for (uint32_t i = 0; i < levels; ++i) {
        CwbvhNode n = test::unit_leaf_node(i, 1);
        if (i + 1 < levels) {
            test::set_unit_internal(n, 0);
            n.child_base = i + 1;
        }
        s.nodes.push_back(n);
        test::add_unit_triangle(s, i);
    }
    test::close_unit_scene(s);
    return s;
}

TEST(TwoLevel, TopLevelAloneIsSafeOnABrokenNodeSection) {
    // Validating only the two-level sections reads NODE for rule 6041's mesh depths: a NODE
    // the validator did not check (wild child_base, cycles by index) must not derail it.
    std::vector<uint8_t> f = standard_file();
    edit_element<CwbvhNode>(f, kSectionNodes, 0, [](CwbvhNode& n) { n.child_base = 0xFFFFFFF0u; });
    edit_element<CwbvhNode>(f, kSectionNodes, 1, [](CwbvhNode& n) {
        n.imask = 0xFF;
        n.child_base = 0;
    });
    ValidateOptions o;
    o.sections = kMaskTwoLevel;
    const Result only_top = validate(f, o);
    EXPECT_TRUE(only_top.ok()) << only_top.describe();
    EXPECT_RULE(validate(f), rule::kNodeChildRange);
}

TEST(TwoLevel, Rule6041DepthOfBothLevels) {
    // Three instances: the third sits in the TLAS's second level (make_two_level).
    const std::vector<test::Placement> three = {test::place(0), test::place(0, 2), test::place(0, 4)};
    const SceneData ok = test::make_two_level({chain_mesh(kMaxWideDepth - 2)}, three);
    ASSERT_EQ(ok.top_nodes.size(), 2u);
    const Result r_ok = deep(test::file_bytes(ok));
    EXPECT_TRUE(r_ok.ok()) << r_ok.describe();  // 2 + 30 = 32 levels together
    const SceneData deep_scene = test::make_two_level({chain_mesh(kMaxWideDepth - 1)}, three);
    EXPECT_RULE(test::check(test::file_bytes(deep_scene)), rule::kTwoLevelDepth);  // 2 + 31
    // The mesh alone is within 5113; only the sum is too deep. With two instances (TLAS one level) it is valid.
    const SceneData shallow = test::make_two_level({chain_mesh(kMaxWideDepth - 1)}, {three[0], three[1]});
    EXPECT_TRUE(test::check(test::file_bytes(shallow)).ok());
    // A TLAS deeper than 32 by itself: 6113 (checked before 6041).
}

// ---- D7 ----

TEST(TwoLevel, DeepCheckD7) {
    auto deep_after = [](auto edit) {
        std::vector<uint8_t> f = standard_file();
        edit(f);
        return deep(f);
    };
    auto expect_d7 = [](const Result& r) {
        EXPECT_FALSE(r.ok());
        EXPECT_NE(r.message.find("D7"), std::string::npos) << r.describe();
    };
    // A world box one ulp too small: valid structure, wrong geometry.
    expect_d7(deep_after([](std::vector<uint8_t>& f) {
        edit_element<InstanceRecord>(f, kSectionInstances, 2, [](InstanceRecord& r) {
            r.world_hi[0] = std::nextafter(r.world_hi[0], -INFINITY);
        });
    }));
    // A mesh box that misses a vertex (its world boxes shrink with it, so only D7 sees it).
    expect_d7(deep_after([](std::vector<uint8_t>& f) {
        edit_element<MeshRecord>(f, kSectionMeshes, 1, [](MeshRecord& m) { m.lo[0] = std::nextafter(m.lo[0], INFINITY); });
    }));
    // A TLAS leaf box that no longer holds its instance's world box.
    expect_d7(deep_after([](std::vector<uint8_t>& f) {
        edit_element<CwbvhNode>(f, kSectionTopNodes, 1, [](CwbvhNode& n) {
            for (int a = 0; a < 3; ++a)
                if (n.q_hi[a][0] > n.q_lo[a][0]) {
                    --n.q_hi[a][0];
                    break;
                }
        });
    }));
    // BNDS smaller than the union of the world boxes.
    expect_d7(deep_after([](std::vector<uint8_t>& f) {
        edit_element<SceneBounds>(f, kSectionBounds, 0, [](SceneBounds& b) { b.hi[0] = b.hi[0] / 2; });
    }));
    // D2 per mesh: a bottom-level leaf box that misses its triangle.
    std::vector<uint8_t> f = standard_file();
    edit_element<CwbvhNode>(f, kSectionNodes, 3, [](CwbvhNode& n) {
        for (int s = 0; s < kWidth; ++s)
            if (!meta_is_empty(n.meta[s]) && n.q_hi[0][s] > n.q_lo[0][s]) {
                --n.q_hi[0][s];
                break;
            }
    });
    const Result r = deep(f);
    ASSERT_FALSE(r.ok());
    EXPECT_TRUE(r.message.find("D2") != std::string::npos || r.message.find("D3") != std::string::npos)
        << r.describe();
}

// ---- transform_host.h ----

TEST(Transforms, InverseConditionAndTolerance) {
    const test::Placement p = test::place(0, 3, -2, 7, 30, 0.25f, true);
    double x[3][4];
    ASSERT_TRUE(invert_affine(p.object_to_world, x));
    EXPECT_LT(affine_determinant(p.object_to_world), 0);  // mirrored
    // X * M = identity (in double, to rounding).
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
            double v = c == 3 ? x[r][3] : 0;
            for (int k = 0; k < 3; ++k) v += x[r][k] * p.object_to_world[k][c];
            EXPECT_NEAR(v, r == c ? 1.0 : 0.0, 1e-6) << r << c;
        }
    // A scaled, mirrored rotation: kappa = (|cos| + |sin|)^2, whatever the scale.
    const double cs = std::cos(3.14159265358979 / 6) + 0.5;
    EXPECT_NEAR(condition_number(p.object_to_world), cs * cs, 1e-6);
    // At the bound: diag(1, 1, 2^-20) has kappa exactly 2^20 (valid); 2^-21 is not.
    float m[3][4];
    identity_transform(m);
    m[2][2] = 0x1p-20f;
    EXPECT_EQ(condition_number(m), kMaxTransformCondition);
    MeshRecord mesh{};
    mesh.hi[0] = mesh.hi[1] = mesh.hi[2] = 1;
    EXPECT_TRUE(make_instance(m, mesh, 0, 0).ok());
    m[2][2] = 0x1p-21f;
    EXPECT_EQ(make_instance(m, mesh, 0, 0).error().rule, rule::kInstCondition);
    m[2][2] = 0;
    EXPECT_EQ(condition_number(m), INFINITY);
    EXPECT_FALSE(invert_affine(m, x));
    m[2][2] = 1e-39f;  // subnormal: the inverse overflows float
    EXPECT_FALSE(make_instance(m, mesh, 0, 0).ok());
    // A huge translation is fine: the condition number ignores it.
    identity_transform(m);
    m[0][3] = 1e30f;
    Expected<InstanceRecord> far = make_instance(m, mesh, 0, 0);
    ASSERT_TRUE(far.ok()) << far.error().describe();
    EXPECT_EQ(far->world_to_object[0][3], -1e30f);
    EXPECT_TRUE(check_instance_transforms(far->object_to_world, far->world_to_object).ok());
}

TEST(Transforms, WorldBoxRoundsOutward) {
    // The corner images are products of floats: exact in long double here, and mostly not floats.
    // The box must hold each exactly; rounding to nearest would cut some off (counted: the bad case).
    int nearest_would_cut = 0;
    for (int k = 1; k < 200; ++k) {
        float m[3][4];
        identity_transform(m);
        m[0][0] = 0.1f * float(k);
        m[0][1] = 1.0f / 3.0f;
        m[0][3] = 1.0f / float(k + 2);
        const float lo[3] = {0.7f, -1.3f, 0}, hi[3] = {1.9f, 2.1f, 0};
        float wlo[3], whi[3];
        transform_box(m, lo, hi, wlo, whi);
        long double ex_lo = INFINITY, ex_hi = -INFINITY;
        for (int c = 0; c < 4; ++c) {
            const long double x = (c & 1) ? hi[0] : lo[0], y = (c & 2) ? hi[1] : lo[1];
            const long double v = (long double)m[0][0] * x + (long double)m[0][1] * y + (long double)m[0][3];
            ex_lo = std::min(ex_lo, v);
            ex_hi = std::max(ex_hi, v);
        }
        EXPECT_LE((long double)wlo[0], ex_lo) << k;
        EXPECT_GE((long double)whi[0], ex_hi) << k;
        nearest_would_cut += (long double)float(double(ex_lo)) > ex_lo || (long double)float(double(ex_hi)) < ex_hi;
    }
    EXPECT_GT(nearest_would_cut, 10);
}

}  // namespace
}  // namespace cwbvh
