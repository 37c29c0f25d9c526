// Validator: one test per rule family, each on a deliberately edited file.
#include <gtest/gtest.h>

#include <cmath>
#include <utility>

#include "cwbvh/format/node_decode.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

using test::check;
using test::entry;
using test::find_entry;
using test::header_of;
using test::reseal;
using test::set_entry;
using test::set_header;

TEST(Validate, AcceptsSyntheticFile) {
    const Result r = check(test::synthetic_file());
    EXPECT_TRUE(r.ok()) << r.describe();
}

TEST(Validate, IdentityAndVersion) {
    std::vector<uint8_t> f = test::synthetic_file();
    EXPECT_RULE(validate(std::span<const uint8_t>()), rule::kTruncatedHeader);
    EXPECT_RULE(validate(std::span<const uint8_t>(f.data(), 5)), rule::kTruncatedHeader);
    EXPECT_RULE(validate(std::span<const uint8_t>(f.data(), 63)), rule::kTruncatedHeader);
    const std::string text = "hello, this is a text file\n";
    EXPECT_RULE(validate({reinterpret_cast<const uint8_t*>(text.data()), text.size()}), rule::kBadMagic);
    {
        auto g = f;
        g[0] = 0x2B;  // 7-bit transfer
        const Result r = check(g);
        EXPECT_EQ(r.status, Status::kNotCwbvh);
        EXPECT_NE(r.message.find("7-bit"), std::string::npos) << r.message;
    }
    {
        auto g = f;
        g.erase(g.begin() + 7);  // CR LF -> LF
        EXPECT_NE(check(g).message.find("CR LF"), std::string::npos);
    }
    {
        auto g = f;
        FileHeader h = header_of(g);
        h.version_major = 2;
        set_header(g, h);
        reseal(g);
        const Result r = check(g);
        EXPECT_EQ(r.status, Status::kUnsupportedVersion);
        EXPECT_RULE(r, rule::kUnsupportedMajor);
    }
    {
        auto g = f;
        FileHeader h = header_of(g);
        h.version_minor = 7;  // newer minor: accepted
        set_header(g, h);
        reseal(g);
        EXPECT_TRUE(check(g).ok()) << check(g).describe();
    }
}

TEST(Validate, Header) {
    const std::vector<uint8_t> f = test::synthetic_file();
    auto edit = [&](auto fn) {
        auto g = f;
        FileHeader h = header_of(g);
        fn(h);
        set_header(g, h);
        reseal(g);
        return g;
    };
    EXPECT_RULE(check(edit([](FileHeader& h) { h.header_size = 80; })), rule::kHeaderSize);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.file_size += 1; })), rule::kFileSize);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.section_table_offset = 68; })), rule::kTableAlignment);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.section_table_offset = 0; })), rule::kTableAlignment);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.section_count = 0x7FFFFFFF; })), rule::kTableOutsideFile);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.section_table_offset = ~uint64_t(7); })), rule::kTableOutsideFile);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.flags = 1; })), rule::kHeaderFlags);
    EXPECT_RULE(check(edit([](FileHeader& h) { h.reserved1 = 1; })), rule::kHeaderReserved);
    auto g = f;
    g[20] ^= 1;  // section_count, not resealed
    EXPECT_EQ(check(g).status, Status::kChecksumMismatch);
    auto trunc = f;
    trunc.resize(f.size() - 1);
    EXPECT_RULE(check(trunc), rule::kFileSize);
    auto longer = f;
    longer.push_back(0);
    EXPECT_RULE(check(longer), rule::kFileSize);
}

TEST(Validate, SectionTable) {
    const std::vector<uint8_t> f = test::synthetic_file();
    const uint32_t nodes = find_entry(f, kSectionNodes);
    const uint32_t tris = find_entry(f, kSectionTriangles);
    auto edit = [&](uint32_t index, auto fn) {
        auto g = f;
        SectionEntry e = entry(g, index);
        fn(e);
        set_entry(g, index, e);
        reseal(g);
        return g;
    };
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.flags |= 4; })), rule::kSectionFlags);
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.reserved = 1; })), rule::kSectionReserved);
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.offset += 8; })), rule::kSectionAlignment);
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.offset = uint64_t(1) << 62; })), rule::kSectionOutsideFile);
    EXPECT_RULE(check(edit(nodes, [&](SectionEntry& e) { e.offset = f.size() / 64 * 64; })), rule::kSectionOutsideFile);
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.offset = 0; })), rule::kSectionOverlapsHeader);
    EXPECT_RULE(check(edit(tris, [&](SectionEntry& e) { e.offset = entry(f, nodes).offset; })), rule::kSectionOverlap);
    // count * size overflows 64 bits: size cannot match.
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.element_count = (uint64_t(1) << 62) + 1; e.size = 80; })),
                rule::kSectionSize);
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.size += 80; })), rule::kSectionSize);
    EXPECT_RULE(check(edit(nodes, [](SectionEntry& e) { e.element_size = 40; e.element_count *= 2; })),
                rule::kElementSize);
    EXPECT_RULE(check(edit(find_entry(f, kSectionBvh2), [&](SectionEntry& e) { e = entry(f, tris); })),
                rule::kDuplicateSection);
    EXPECT_RULE(check(edit(find_entry(f, kSectionBounds), [](SectionEntry& e) { e.type = fourcc('Z', 'Z', 'Z', 'Z'); e.flags = 0; })),
                rule::kMissingSection);
    // Unknown required section: rejected; unknown optional: skipped.
    const uint32_t bvh2 = find_entry(f, kSectionBvh2);
    const Result req = check(edit(bvh2, [](SectionEntry& e) { e.type = fourcc('X', 'T', 'R', 'A'); e.flags = 1; }));
    EXPECT_RULE(req, rule::kUnknownRequiredSection);
    EXPECT_EQ(req.status, Status::kUnsupported);
    const Result opt = check(edit(bvh2, [](SectionEntry& e) { e.type = fourcc('X', 'T', 'R', 'A'); e.flags = 0; }));
    EXPECT_TRUE(opt.ok()) << opt.describe();
    // Padding must be zero.
    auto g = f;
    const SectionEntry first = entry(g, 0);
    ASSERT_GT(first.offset, 64 + 9 * 48u);
    g[first.offset - 1] = 1;
    reseal(g);
    EXPECT_RULE(check(g), rule::kNonZeroPadding);
    // Payload checksum.
    auto p = f;
    p[entry(p, nodes).offset + 1] ^= 0x40;
    EXPECT_RULE(check(p), rule::kSectionChecksum);
}

TEST(Validate, Counts) {
    const std::vector<uint8_t> f = test::synthetic_file();
    auto edit_count = [&](uint32_t type, uint64_t count) {
        auto g = f;
        const uint32_t i = find_entry(g, type);
        SectionEntry e = entry(g, i);
        e.element_count = count;
        e.size = count * e.element_size;
        set_entry(g, i, e);
        reseal(g);
        return g;
    };
    EXPECT_RULE(check(edit_count(kSectionNodes, 0)), rule::kElementCount);
    EXPECT_RULE(check(edit_count(kSectionBounds, 0)), rule::kElementCount);
    // INDX count vs the PMAP total is a content rule (5802): see SourceRanges.
}

// PMAP: synthetic_file() has 40 stored triangles in 5 ranges of 8.
TEST(Validate, SourceRanges) {
    const std::vector<uint8_t> f = test::synthetic_file();
    auto range = [&](uint64_t i, auto fn) {
        auto g = f;
        test::edit_element<SourceRange>(g, kSectionSourceMap, i, fn);
        return g;
    };
    EXPECT_RULE(check(range(2, [](SourceRange& r) { r.count = 0; })), rule::kPmapRangeEmpty);
    EXPECT_RULE(check(range(0, [](SourceRange& r) { r.first = 1; })), rule::kPmapRangeOrder);
    // A gap: range 1 ends one early, so range 2 does not start where it ends.
    EXPECT_RULE(check(range(1, [](SourceRange& r) { r.count = 7; })), rule::kPmapRangeOrder);
    EXPECT_RULE(check(range(4, [](SourceRange& r) { r.first_triangle = 0xFFFFFFFAu; })), rule::kPmapRangeLimit);
    // The last range grows: 44 stored triangles, but TRIS holds only 40 records (every stored
    // triangle needs one): the total is bounded by the file (rule 5305, issue 21 finding 1).
    EXPECT_RULE(check(range(4, [](SourceRange& r) { r.count = 12; })), rule::kPmapTotal);
    {
        // INDX still has 40: its own rule, seen when PMAP and TRIS are not selected.
        ValidateOptions o;
        o.sections = kMaskAll & ~(kMaskSourceMap | kMaskTriangles);
        EXPECT_RULE(validate(range(4, [](SourceRange& r) { r.count = 12; }), o), rule::kIndexCount);
    }
    // The last range shrinks: TRIS names stored triangle 39, which PMAP no longer covers.
    EXPECT_RULE(check(range(4, [](SourceRange& r) { r.count = 7; })), rule::kTriPrim);
    // A run ending past 2^32 (first + count computed in 64 bits).
    {
        auto g = f;
        test::edit_element<SourceRange>(g, kSectionSourceMap, 0, [](SourceRange& r) { r.count = 0xFFFFFFFFu; });
        test::edit_element<SourceRange>(g, kSectionSourceMap, 1, [](SourceRange& r) { r.first = 0xFFFFFFFFu; });
        ValidateOptions o;
        o.sections = kMaskSourceMap;
        EXPECT_RULE(validate(g, o), rule::kPmapRangeLimit);  // range 1 ends at 2^32 + 7
    }
}

TEST(Validate, NodeContent) {
    SyntheticOptions so;  // three levels, a root with internal children and an outlier's leaf
    so.triangles = 300;
    so.outlier = true;
    const std::vector<uint8_t> f = test::file_bytes(make_synthetic_scene(so));
    auto node = [&](uint64_t i, auto fn) {
        auto g = f;
        test::edit_element<CwbvhNode>(g, kSectionNodes, i, fn);
        return g;
    };
    // Find a root slot with an internal child and one with a leaf.
    const SectionEntry nodes = entry(f, find_entry(f, kSectionNodes));
    auto read_node = [&](uint64_t i) {
        CwbvhNode n;
        std::memcpy(&n, f.data() + nodes.offset + i * sizeof n, sizeof n);
        return n;
    };
    const CwbvhNode root = read_node(0);
    int internal = -1, leaf = -1, empty = -1;
    uint64_t empty_node = 0;
    for (int s = 0; s < 8; ++s) {
        if (meta_is_internal(root.meta[s]) && internal < 0) internal = s;
        if (meta_is_leaf(root.meta[s]) && leaf < 0) leaf = s;
    }
    for (uint64_t i = 0; i < nodes.element_count && empty < 0; ++i)
        for (int s = 0; s < 8 && empty < 0; ++s)
            if (meta_is_empty(read_node(i).meta[s])) empty = s, empty_node = i;
    ASSERT_GE(internal, 0);
    ASSERT_GE(leaf, 0);
    ASSERT_GE(empty, 0);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.e[1] = 0; })), rule::kNodeExponent);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.e[2] = 255; })), rule::kNodeExponent);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.meta[leaf] = 0x40 | 1; })), rule::kNodeMeta);   // unary 0b010
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.meta[leaf] = make_meta_leaf(3, 22); })), rule::kNodeMeta);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.meta[internal] = make_meta_internal((internal + 1) % 8); })),
                rule::kNodeMeta);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.imask ^= uint8_t(1u << internal); })), rule::kNodeImask);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.imask |= uint8_t(1u << leaf); })), rule::kNodeImask);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.child_base = 0; })), rule::kNodeChildOrder);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.child_base = 0xFFFFFFF0u; })), rule::kNodeChildRange);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.child_base += 1; })), rule::kNodeParents);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.tri_base = 0xFFFFFFFFu; })), rule::kNodeLeafRange);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.tri_base += 1; })), rule::kNodeTriangleUse);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.meta[leaf] = make_meta_leaf(meta_leaf_count(n.meta[leaf]), 20); })),
                rule::kNodeLeafLayout);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.q_lo[0][leaf] = 255; n.q_hi[0][leaf] = 1; })),
                rule::kNodePlaneOrder);
    EXPECT_RULE(check(node(empty_node, [&](CwbvhNode& n) { n.q_hi[2][empty] = 1; })), rule::kNodeEmptySlot);
    EXPECT_RULE(check(node(0, [](CwbvhNode& n) { n.p[0] = INFINITY; })), rule::kNodeNonFinite);
    EXPECT_RULE(check(node(0, [&](CwbvhNode& n) { n.e[0] = 254; n.q_hi[0][leaf] = 255; n.p[0] = 3e38f; })),
                rule::kNodeNonFinite);
}

TEST(Validate, OtherSectionContent) {
    const std::vector<uint8_t> f = test::synthetic_file();
    auto g = f;
    test::edit_element<TriangleRecord>(g, kSectionTriangles, 3, [](TriangleRecord& t) { t.prim = 40; });
    EXPECT_RULE(check(g), rule::kTriPrim);
    g = f;
    test::edit_element<TriangleRecord>(g, kSectionTriangles, 3, [](TriangleRecord& t) { t.v1[1] = NAN; });
    EXPECT_RULE(check(g), rule::kTriNonFinite);
    g = f;
    test::edit_element<SourceRange>(g, kSectionSourceMap, 2, [](SourceRange& r) { r.input = 1; });
    EXPECT_RULE(check(g), rule::kPmapInput);
    g = f;
    test::edit_element<SceneBounds>(g, kSectionBounds, 0, [](SceneBounds& b) { b.lo[0] = b.hi[0] + 1; });
    EXPECT_RULE(check(g), rule::kBoundsInvalid);
    g = f;
    test::edit_element<BuildInfo>(g, kSectionBuildInfo, 0, [](BuildInfo& b) { b.reserved[100] = 1; });
    EXPECT_RULE(check(g), rule::kBuildReserved);
    g = f;
    test::edit_element<Bvh2Node>(g, kSectionBvh2, 0, [](Bvh2Node& n) { n.child[0] = 0; });
    EXPECT_RULE(check(g), rule::kBvh2Child);
    g = f;
    test::edit_element<Bvh2Node>(g, kSectionBvh2, 0, [](Bvh2Node& n) { n.child[1] = n.child[0]; });
    EXPECT_RULE(check(g), rule::kBvh2Parents);
    g = f;
    test::edit_element<Bvh2Node>(g, kSectionBvh2, 0, [](Bvh2Node& n) { n.child[0] = ~1000; });
    EXPECT_RULE(check(g), rule::kBvh2Leaf);
    g = f;
    test::edit_element<Bvh2Node>(g, kSectionBvh2, 0, [](Bvh2Node& n) { n.leaf_count[1] = 1; });
    EXPECT_RULE(check(g), rule::kBvh2Reserved);
    g = f;
    test::edit_element<Bvh2Node>(g, kSectionBvh2, 0, [](Bvh2Node& n) { n.c1_hi_y = -INFINITY; });
    EXPECT_RULE(check(g), rule::kBvh2NonFinite);
    g = f;
    test::edit_element<float>(g, kSectionVertices, 7, [](float& v) { v = NAN; });
    EXPECT_RULE(check(g), rule::kVertNonFinite);
    g = f;
    test::edit_element<uint32_t>(g, kSectionIndices, 5, [](uint32_t& i) { i = 120; });
    EXPECT_RULE(check(g), rule::kIndexRange);
    g = f;
    test::edit_element<char>(g, kSectionSourceNames, 9, [](char& c) { c = 'x'; });
    EXPECT_RULE(check(g), rule::kNamesTerminator);
    // An empty SRCN does not end with a NUL either (3.7): no names, so a PMAP `input` of 0
    // would name nothing (the names become zero padding; the entry says 0 bytes).
    g = f;
    {
        const uint32_t k = test::find_entry(g, kSectionSourceNames);
        SectionEntry e = test::entry(g, k);
        std::memset(g.data() + e.offset, 0, e.size);
        e.size = e.element_count = 0;
        test::set_entry(g, k, e);
        test::reseal(g);
    }
    EXPECT_RULE(check(g), rule::kNamesTerminator);
}

/// A file whose binary BVH is a BV2L section (leaf ranges of up to 3 records).
std::vector<uint8_t> leaf_range_file(uint32_t triangles = 40) {
    SyntheticOptions o;
    o.triangles = triangles;
    o.bvh2_leaf_ranges = true;
    return test::file_bytes(make_synthetic_scene(o));
}

/// Index of the first BV2L node with a leaf child, and that child.
std::pair<uint64_t, int> first_leaf_child(const std::vector<uint8_t>& f) {
    const SectionEntry e = entry(f, find_entry(f, kSectionBvh2Leaves));
    for (uint64_t i = 0; i < e.element_count; ++i) {
        Bvh2Node n;
        std::memcpy(&n, f.data() + e.offset + i * sizeof n, sizeof n);
        for (int c = 0; c < 2; ++c)
            if (n.child[c] < 0) return {i, c};
    }
    throw std::runtime_error("no leaf child");
}

TEST(Validate, LeafRangeSection) {
    const std::vector<uint8_t> f = leaf_range_file();
    ASSERT_TRUE(check(f).ok()) << check(f).describe();
    EXPECT_EQ(header_of(f).version_minor, 1u) << "a file with BV2L is format 1.1";
    EXPECT_EQ(header_of(test::synthetic_file()).version_minor, 0u) << "a file without 1.1 sections stays 1.0";
    const auto [leaf_node, leaf_c] = first_leaf_child(f);
    const uint32_t tris = uint32_t(entry(f, find_entry(f, kSectionTriangles)).element_count);
    auto edit = [&](auto fn) {
        auto g = f;
        test::edit_element<Bvh2Node>(g, kSectionBvh2Leaves, leaf_node, fn);
        return g;
    };
    const int c = leaf_c;
    // Counts outside 1..4.
    EXPECT_RULE(check(edit([&](Bvh2Node& n) { n.leaf_count[c] = 0; })), rule::kBvh2LeafCount);
    EXPECT_RULE(check(edit([&](Bvh2Node& n) { n.leaf_count[c] = kMaxBvh2LeafTriangles + 1; })), rule::kBvh2LeafCount);
    // A shorter range leaves a record in no leaf: no ray could reach it (rule 5610).
    Bvh2Node leaf;
    std::memcpy(&leaf, f.data() + entry(f, find_entry(f, kSectionBvh2Leaves)).offset + leaf_node * sizeof leaf,
                sizeof leaf);
    if (leaf.leaf_count[c] > 1)
        EXPECT_RULE(check(edit([&](Bvh2Node& n) { n.leaf_count[c] = 1; })), rule::kBvh2TriangleUse);
    else
        EXPECT_TRUE(check(edit([&](Bvh2Node& n) { n.leaf_count[c] = 1; })).ok());
    // Ranges past the end of TRIS.
    EXPECT_RULE(check(edit([&](Bvh2Node& n) { n.child[c] = ~int32_t(tris - 1); n.leaf_count[c] = 2; })),
                rule::kBvh2LeafRange);
    // In range, but the last records are then in two leaves (rule 5610).
    EXPECT_RULE(check(edit([&](Bvh2Node& n) { n.child[c] = ~int32_t(tris - 2); n.leaf_count[c] = 2; })),
                rule::kBvh2TriangleUse);
    EXPECT_RULE(check(edit([&](Bvh2Node& n) { n.child[c] = ~int32_t(tris); n.leaf_count[c] = 1; })),
                rule::kBvh2LeafRange);
    // An internal child with a count.
    {
        auto g = f;
        test::edit_element<Bvh2Node>(g, kSectionBvh2Leaves, 0, [](Bvh2Node& n) {
            for (int k = 0; k < 2; ++k)
                if (n.child[k] >= 0) n.leaf_count[k] = 1;
        });
        EXPECT_RULE(check(g), rule::kBvh2InternalCount);
    }
    // The rules shared with BVH2 apply too.
    EXPECT_RULE(check(edit([](Bvh2Node& n) { n.c0_lo_y = NAN; })), rule::kBvh2NonFinite);
    {
        auto g = f;
        test::edit_element<Bvh2Node>(g, kSectionBvh2Leaves, 0, [](Bvh2Node& n) {
            n.child[0] = 0;
            n.leaf_count[0] = 0;
        });
        EXPECT_RULE(check(g), rule::kBvh2Child);
    }
    // Section table: empty, and more TRIS records than a packed leaf allows.
    {
        auto g = f;
        const uint32_t i = find_entry(g, kSectionBvh2Leaves);
        SectionEntry e = entry(g, i);
        e.element_count = 0;
        e.size = 0;
        set_entry(g, i, e);
        reseal(g);
        EXPECT_FALSE(check(g).ok());
    }
    {
        auto g = f;
        const uint32_t i = find_entry(g, kSectionTriangles);
        SectionEntry e = entry(g, i);
        e.element_count = kMaxBvh2LeafTris + 1;  // size no longer matches: caught by 4004 first
        EXPECT_LT(tris, kMaxBvh2LeafTris);
        set_entry(g, i, e);
        reseal(g);
        EXPECT_FALSE(check(g).ok());
    }
}

TEST(Validate, LegacyAndLeafRangeSectionsTogether) {
    // Both binary sections in one file: each is checked by its own rules.
    SyntheticOptions o;
    o.triangles = 30;
    o.bvh2_leaf_ranges = true;
    SceneData ranges = make_synthetic_scene(o);
    o.bvh2_leaf_ranges = false;
    const SceneData legacy = make_synthetic_scene(o);
    Writer w;
    add_scene_sections(w, ranges);
    w.add_array<Bvh2Node>(kSectionBvh2, 0, legacy.bvh2);
    std::vector<uint8_t> f;
    ASSERT_TRUE(w.to_bytes(f).ok());
    EXPECT_TRUE(check(f).ok()) << check(f).describe();
    auto g = f;
    test::edit_element<Bvh2Node>(g, kSectionBvh2, 0, [](Bvh2Node& n) { n.leaf_count[0] = 2; });
    EXPECT_RULE(check(g), rule::kBvh2Reserved);
}

TEST(Validate, WithoutChecksumsStructureIsStillChecked) {
    const std::vector<uint8_t> f = test::synthetic_file();
    const SectionEntry tris = entry(f, find_entry(f, kSectionTriangles));
    auto g = f;
    g[tris.offset + 16 + 2] ^= 0x01;  // low mantissa bit of v1.x of record 0: still a finite float
    EXPECT_RULE(check(g, true), rule::kSectionChecksum);
    EXPECT_TRUE(check(g, false).ok()) << check(g, false).describe();
    auto h = f;
    const SectionEntry nodes = entry(h, find_entry(h, kSectionNodes));
    h[nodes.offset + 16] ^= 0x05;  // root child_base
    EXPECT_RULE(check(h, true), rule::kSectionChecksum);
    const Result r = check(h, false);
    EXPECT_FALSE(r.ok());
    EXPECT_GE(r.rule, 5100u);
    EXPECT_LT(r.rule, 5200u);
    // The meta checksum is always verified.
    auto m = f;
    m[64 + 8] ^= 1;  // first entry's offset
    EXPECT_RULE(check(m, false), rule::kMetaChecksum);
}

TEST(Validate, SectionSelectionSkipsUnrequestedContent) {
    std::vector<uint8_t> f = test::synthetic_file();
    test::edit_element<uint32_t>(f, kSectionIndices, 5, [](uint32_t& i) { i = 999; });
    ValidateOptions o;
    o.sections = kMaskNodes | kMaskTriangles;
    EXPECT_TRUE(validate(f, o).ok());
    EXPECT_RULE(validate(f), rule::kIndexRange);
    // Table rules still run on every entry.
    auto g = f;
    SectionEntry e = entry(g, find_entry(g, kSectionIndices));
    e.offset += 64 * 1000;
    set_entry(g, find_entry(g, kSectionIndices), e);
    reseal(g);
    EXPECT_RULE(validate(g, o), rule::kSectionOutsideFile);
}

}  // namespace
}  // namespace cwbvh
