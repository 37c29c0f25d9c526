// Issue 21: a crafted-file attack on format 1.1. One test per finding (1-7), each on hostile
// bytes generated here from a valid synthetic file (no committed blobs). The tool runs go
// through `timeout` (run_cwbvh), so a hang shows as exit 124 instead of a stuck suite.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cfloat>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "cwbvh/format/deep_check.h"
#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/loader/loader.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

namespace fs = std::filesystem;
using test::entry;
using test::find_entry;
using test::header_of;

test::ToolRun run(const std::string& args) { return test::run_cwbvh(args); }

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

std::string slurp(const std::string& path) {
    std::vector<uint8_t> bytes;
    if (!read_regular_file(path, uint64_t(1) << 30, bytes).ok()) return "<unreadable>";
    return std::string(bytes.begin(), bytes.end());
}

std::vector<uint8_t> leaf_range_file() {
    SyntheticOptions o;
    o.bvh2_leaf_ranges = true;
    return test::file_bytes(make_synthetic_scene(o));
}

/// A FIFO in the test's temp dir (nobody ever writes to it).
std::string make_fifo(const std::string& name) {
    const std::string path = test::temp_dir() + "/" + name;
    ::unlink(path.c_str());
    if (::mkfifo(path.c_str(), 0600) != 0) throw std::runtime_error("mkfifo " + path);
    return path;
}

/// A small valid ray file for `trace`.
std::string ray_file(const std::string& name) {
    Ray r{};
    r.org[2] = -10;
    r.dir[2] = 1;
    r.tmax = INFINITY;
    const std::string path = test::temp_dir() + "/" + name;
    EXPECT_TRUE(write_ray_file(path, &r, 1).ok());
    return path;
}

// Finding 1: a PMAP total far beyond what the file holds passed plain validation, and
// `validate --deep` allocated per stored triangle by it (16 GiB for a 1.1 KB file: abort, exit 134).
TEST(Hostile21, Finding1_PmapTotalIsBoundedByTheFile) {
    std::vector<uint8_t> f = test::synthetic_file();
    const uint64_t ranges = entry(f, find_entry(f, kSectionSourceMap)).element_count;
    test::edit_element<SourceRange>(f, kSectionSourceMap, ranges - 1,
                                    [](SourceRange& r) { r.count = 0xFFFFFFFFu - r.first; });
    EXPECT_RULE(test::check(f), rule::kPmapTotal);
    const std::string path = test::write_temp("h21_pmap.cwbvh", f);
    const test::ToolRun deep = run("validate --deep " + path);
    EXPECT_EQ(deep.code, 1) << deep.out;
    EXPECT_EQ(test::count_lines(deep.out), 1u) << deep.out;
    EXPECT_TRUE(contains(deep.out, "[rule 5305]")) << deep.out;

    // The library's deep check bounds the count itself before sizing anything by it.
    const std::vector<uint8_t> good = test::synthetic_file();
    FileLayout layout;
    ASSERT_TRUE(validate(good, {}, &layout).ok());
    const auto payload = [&](uint32_t type) { return layout.payload(*layout.find(type)); };
    const std::span<const CwbvhNode> nodes(reinterpret_cast<const CwbvhNode*>(payload(kSectionNodes).data()),
                                           payload(kSectionNodes).size() / sizeof(CwbvhNode));
    const std::span<const TriangleRecord> tris(
        reinterpret_cast<const TriangleRecord*>(payload(kSectionTriangles).data()),
        payload(kSectionTriangles).size() / sizeof(TriangleRecord));
    const Result r = deep_check(nodes, tris, uint64_t(1) << 32);
    EXPECT_FALSE(r.ok());
    EXPECT_TRUE(contains(r.message, "D4")) << r.message;
}

// Finding 1, the tool's edge: an allocation that fails ends as one line and exit 1, not as an
// uncaught std::bad_alloc (abort, exit 134). 16384 x 16384 rays need 8 GiB; 1 GB of address space.
TEST(Hostile21, Finding1_OutOfMemoryIsOneLineAndExitOne) {
#if defined(__SANITIZE_ADDRESS__)
    GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit allows";
#endif
    const std::string scene = test::write_temp("h21_oom.cwbvh", test::synthetic_file());
    const std::string out = test::temp_dir() + "/h21_oom.rays";
    const test::ToolRun r = test::run_cwbvh(
        "rays " + scene + " --primary --width 16384 --height 16384 --camera 0,0,-5,0,0,0,45 -o " + out,
        "ulimit -v 1000000; ");
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_TRUE(contains(r.out, "cwbvh: error: rays: out of memory")) << r.out;
}

// Finding 2: File::open opened before checking the type, so a FIFO blocked info, validate and
// trace forever; --rays FIFO hung, --rays /dev/zero read until memory ran out.
TEST(Hostile21, Finding2_FifosAndDevicesAreRefusedWithoutBlocking) {
    const std::string fifo = make_fifo("h21.fifo");
    for (const std::string verb : {"info ", "validate ", "validate --deep "}) {
        const test::ToolRun r = run(verb + fifo);
        EXPECT_EQ(r.code, 1) << verb << r.out;
        EXPECT_TRUE(contains(r.out, "is a FIFO")) << r.out;
        EXPECT_TRUE(contains(r.out, "[rule 1002]")) << r.out;
    }
    const Expected<File> opened = File::open(fifo);
    ASSERT_FALSE(opened.ok());
    EXPECT_EQ(opened.error().rule, rule::kNotRegularFile);

    const std::string scene = test::write_temp("h21_scene.cwbvh", test::synthetic_file());
    const test::ToolRun t = run("trace " + fifo + " --rays " + ray_file("h21_a.rays"));
    EXPECT_EQ(t.code, 1) << t.out;
    const test::ToolRun rf = run("trace " + scene + " --rays " + fifo);
    EXPECT_EQ(rf.code, 1) << rf.out;
    EXPECT_TRUE(contains(rf.out, "is a FIFO")) << rf.out;
    if (fs::exists("/dev/zero")) {
        const test::ToolRun z = run("trace " + scene + " --rays /dev/zero");
        EXPECT_EQ(z.code, 1) << z.out;
        EXPECT_TRUE(contains(z.out, "is a device")) << z.out;
    }
    std::vector<Ray> rays;
    EXPECT_FALSE(read_ray_file(fifo, rays).ok());

    // A header announcing more records than the file holds: refused before any allocation.
    RayFileHeader h{};
    std::memcpy(h.magic, kRayFileMagic, 8);
    h.version_major = kRayFileVersionMajor;
    h.record_size = sizeof(Ray);
    h.count = uint64_t(1) << 40;
    std::vector<uint8_t> bytes(sizeof h);
    std::memcpy(bytes.data(), &h, sizeof h);
    const Result big = read_ray_file(test::write_temp("h21_big.rays", bytes), rays);
    EXPECT_FALSE(big.ok());
    EXPECT_TRUE(contains(big.message, "does not match count")) << big.message;
}

// Finding 3: rays -o, trace --hits and render -o overwrote an input named as the output
// (same path, symlink, hard link) and exited 0.
TEST(Hostile21, Finding3_OutputsNeverOverwriteAnInput) {
    const std::vector<uint8_t> bytes = test::synthetic_file();
    const std::string scene = test::write_temp("h21_in.cwbvh", bytes);
    const std::string link = test::temp_dir() + "/h21_in_link.cwbvh";
    const std::string hard = test::temp_dir() + "/h21_in_hard.cwbvh";
    fs::remove(link);
    fs::remove(hard);
    fs::create_symlink(scene, link);
    fs::create_hard_link(scene, hard);
    const std::string rays = ray_file("h21_in.rays");
    const std::string rays_before = slurp(rays);
    for (const std::string& out : {scene, link, hard}) {
        const test::ToolRun r = run("rays " + scene + " --primary --width 4 --height 4 -o " + out);
        EXPECT_EQ(r.code, 1) << r.out;
        EXPECT_TRUE(contains(r.out, "refusing to overwrite")) << r.out;
        const test::ToolRun render = run("render " + scene + " --width 4 --height 4 -o " + out);
        EXPECT_EQ(render.code, 1) << render.out;
        EXPECT_TRUE(contains(render.out, "refusing to overwrite")) << render.out;
        const test::ToolRun hits = run("trace " + scene + " --rays " + rays + " --hits " + out);
        EXPECT_EQ(hits.code, 1) << hits.out;
        EXPECT_TRUE(contains(hits.out, "refusing to overwrite")) << hits.out;
    }
    const test::ToolRun onto_rays = run("trace " + scene + " --rays " + rays + " --hits " + rays);
    EXPECT_EQ(onto_rays.code, 1) << onto_rays.out;
    EXPECT_EQ(slurp(scene), std::string(bytes.begin(), bytes.end())) << "the input was overwritten";
    EXPECT_EQ(slurp(rays), rays_before) << "the ray file was overwritten";
    // A fresh output still works.
    const std::string fresh = test::temp_dir() + "/h21_fresh.hits";
    fs::remove(fresh);
    EXPECT_EQ(run("trace " + scene + " --rays " + rays + " --hits " + fresh).code, 0);
}

// Finding 4: nothing checked the BV2L/BVH2 geometry: leaves all pointing at the same records,
// or inverted boxes, passed `validate --deep`.
TEST(Hostile21, Finding4_BinaryTreeGeometryIsProven) {
    const std::vector<uint8_t> f = leaf_range_file();
    ASSERT_TRUE(test::check(f).ok());
    const SectionEntry e = entry(f, find_entry(f, kSectionBvh2Leaves));
    // Every leaf points at records 0..2.
    std::vector<uint8_t> same = f;
    for (uint64_t i = 0; i < e.element_count; ++i)
        test::edit_element<Bvh2Node>(same, kSectionBvh2Leaves, i, [](Bvh2Node& n) {
            for (int c = 0; c < 2; ++c)
                if (n.child[c] < 0) {
                    n.child[c] = ~0;
                    n.leaf_count[c] = 3;
                }
        });
    EXPECT_RULE(test::check(same), rule::kBvh2TriangleUse);

    // Inverted boxes: structurally fine (finite), geometrically wrong.
    std::vector<uint8_t> inverted = f;
    for (uint64_t i = 0; i < e.element_count; ++i)
        test::edit_element<Bvh2Node>(inverted, kSectionBvh2Leaves, i, [](Bvh2Node& n) {
            std::swap(n.c0_lo_x, n.c0_hi_x);
            std::swap(n.c1_lo_y, n.c1_hi_y);
        });
    ASSERT_TRUE(test::check(inverted).ok()) << "finite boxes pass the structural rules";
    const std::string good_path = test::write_temp("h21_bv2l.cwbvh", f);
    const std::string bad_path = test::write_temp("h21_bv2l_inverted.cwbvh", inverted);
    const test::ToolRun good = run("validate --deep " + good_path);
    EXPECT_EQ(good.code, 0) << good.out;
    EXPECT_TRUE(contains(good.out, "BV2L")) << good.out;
    const test::ToolRun bad = run("validate --deep " + bad_path);
    EXPECT_EQ(bad.code, 1) << bad.out;
    EXPECT_TRUE(contains(bad.out, "deep check D6: BV2L")) << bad.out;

    // A shrunken box: its subtree's triangles poke out.
    std::vector<uint8_t> shrunk = f;
    test::edit_element<Bvh2Node>(shrunk, kSectionBvh2Leaves, 0, [](Bvh2Node& n) {
        n.c0_hi_x = n.c0_lo_x;
        n.c1_hi_x = n.c1_lo_x;
    });
    ASSERT_TRUE(test::check(shrunk).ok());
    const test::ToolRun s = run("validate --deep " + test::write_temp("h21_bv2l_shrunk.cwbvh", shrunk));
    EXPECT_EQ(s.code, 1) << s.out;
    EXPECT_TRUE(contains(s.out, "deep check D6")) << s.out;

    // A tree over a single record: the root's two children are both that leaf (spec 3.6).
    for (const bool ranges : {true, false}) {
        SyntheticOptions one;
        one.triangles = 1;
        one.bvh2_leaf_ranges = ranges;
        const std::string p = test::write_temp("h21_one.cwbvh", test::file_bytes(make_synthetic_scene(one)));
        const test::ToolRun r = run("validate --deep " + p);
        EXPECT_EQ(r.code, 0) << r.out;
    }

    // The legacy BVH2 section gets the same proof.
    const std::vector<uint8_t> legacy = test::synthetic_file();
    const test::ToolRun l = run("validate --deep " + test::write_temp("h21_bvh2.cwbvh", legacy));
    EXPECT_EQ(l.code, 0) << l.out;
    EXPECT_TRUE(contains(l.out, "BVH2")) << l.out;
    std::vector<uint8_t> legacy_bad = legacy;
    test::edit_element<Bvh2Node>(legacy_bad, kSectionBvh2, 0, [](Bvh2Node& n) { std::swap(n.c0_lo_z, n.c0_hi_z); });
    const test::ToolRun lb = run("validate --deep " + test::write_temp("h21_bvh2_bad.cwbvh", legacy_bad));
    EXPECT_EQ(lb.code, 1) << lb.out;
    EXPECT_TRUE(contains(lb.out, "deep check D6: BVH2")) << lb.out;
}

// Finding 5: a non-root node with no used slot passed, even with a NaN origin or an exponent
// byte of 0 or 255 (spec 3.1 item 1).
TEST(Hostile21, Finding5_NonRootNodeNeedsAUsedSlot) {
    const std::vector<uint8_t> f = test::synthetic_file();
    ASSERT_GT(entry(f, find_entry(f, kSectionNodes)).element_count, 1u);
    for (int variant = 0; variant < 3; ++variant) {
        std::vector<uint8_t> g = f;
        test::edit_element<CwbvhNode>(g, kSectionNodes, 1, [&](CwbvhNode& n) {
            std::memset(n.meta, 0, sizeof n.meta);
            std::memset(n.q_lo, 0, sizeof n.q_lo);
            std::memset(n.q_hi, 0, sizeof n.q_hi);
            n.imask = 0;
            n.child_base = 0;
            n.tri_base = 0;
            if (variant == 1) n.p[0] = NAN;
            if (variant == 2) n.e[1] = 255, n.e[2] = 0;
        });
        const Result r = test::check(g);
        EXPECT_RULE(r, rule::kNodeEmpty);
        EXPECT_TRUE(contains(r.message, "node 1")) << r.message;
    }
    // The root of an empty scene is still fine.
    SyntheticOptions empty;
    empty.triangles = 0;
    empty.bvh2 = false;
    const Result e = test::check(test::file_bytes(make_synthetic_scene(empty)));
    EXPECT_TRUE(e.ok()) << e.describe();
}

// Finding 6: rule 4001 printed the flags in decimal after "0x"; --rays DIR said "read error".
TEST(Hostile21, Finding6_MessagesSayWhatIsWrong) {
    std::vector<uint8_t> f = test::synthetic_file();
    SectionEntry e = entry(f, 0);
    e.flags = 0x10;
    test::set_entry(f, 0, e);
    test::reseal(f);
    const Result r = test::check(f);
    EXPECT_RULE(r, rule::kSectionFlags);
    EXPECT_TRUE(contains(r.message, "0x00000010")) << r.message;
    EXPECT_FALSE(contains(r.message, "0x16")) << r.message;

    const std::string scene = test::write_temp("h21_msg.cwbvh", test::synthetic_file());
    const test::ToolRun dir = run("trace " + scene + " --rays " + test::temp_dir());
    EXPECT_EQ(dir.code, 1) << dir.out;
    EXPECT_TRUE(contains(dir.out, test::temp_dir() + ": is a directory")) << dir.out;
}

// Finding 7: bytes after the last section were accepted; an unknown optional section's checksum
// was never verified; a BNDS of +-FLT_MAX made `cwbvh rays` write only invalid rays, exit 0.
TEST(Hostile21, Finding7_TrailingBytesUnknownChecksumsAndCameraAtInfinity) {
    const std::vector<uint8_t> f = test::synthetic_file();
    for (const size_t extra : {size_t(1), size_t(64)}) {
        std::vector<uint8_t> g = f;
        g.resize(g.size() + extra, 0);
        FileHeader h = header_of(g);
        h.file_size = g.size();
        test::set_header(g, h);
        test::reseal(g);
        EXPECT_RULE(test::check(g), rule::kTrailingBytes);
    }

    // BVH2 renamed to an unknown optional type, then one payload byte changed.
    std::vector<uint8_t> u = f;
    const uint32_t index = find_entry(u, kSectionBvh2);
    SectionEntry e = entry(u, index);
    e.type = fourcc('X', 'T', 'R', 'A');
    e.flags = 0;
    test::set_entry(u, index, e);
    test::reseal(u);
    ASSERT_TRUE(test::check(u).ok());
    u[e.offset + 3] ^= 0x20;
    const Result bad = test::check(u);
    EXPECT_RULE(bad, rule::kSectionChecksum);
    EXPECT_TRUE(contains(bad.message, "XTRA")) << bad.message;
    EXPECT_TRUE(test::check(u, false).ok()) << "without checksums the unknown section is skipped";
    ValidateOptions only_nodes;
    only_nodes.sections = kMaskNodes | kMaskTriangles;
    EXPECT_TRUE(validate(u, only_nodes).ok()) << "a reader that skips it need not verify it";

    // Bounds at +-FLT_MAX are valid (finite, lo <= hi), but no default camera fits them.
    std::vector<uint8_t> wide = f;
    test::edit_element<SceneBounds>(wide, kSectionBounds, 0, [](SceneBounds& b) {
        for (int a = 0; a < 3; ++a) b.lo[a] = -FLT_MAX, b.hi[a] = FLT_MAX;
    });
    ASSERT_TRUE(test::check(wide).ok());
    const std::string path = test::write_temp("h21_not_in_catalog.cwbvh", wide);
    const std::string out = test::temp_dir() + "/h21_inf.rays";
    fs::remove(out);
    const test::ToolRun r = run("rays " + path + " --primary --width 4 --height 4 -o " + out);
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_TRUE(contains(r.out, "cannot place the default camera")) << r.out;
    EXPECT_FALSE(fs::exists(out));
    const test::ToolRun render = run("render " + path + " --width 4 --height 4 -o " + test::temp_dir() + "/h21.png");
    EXPECT_EQ(render.code, 1) << render.out;
    // A camera given by hand still works.
    const test::ToolRun by_hand = run("rays " + path + " --primary --width 4 --height 4 --camera 0,0,-5,0,0,0,45 -o " + out);
    EXPECT_EQ(by_hand.code, 0) << by_hand.out;
}

}  // namespace
}  // namespace cwbvh
