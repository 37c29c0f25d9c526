// The binary BVH with leaf ranges (BV2L, spec 3.6) on compiled scenes:
//   - its leaves are ranges that cover every TRIS record exactly once, and every
//     leaf's triangles lie in its box (split references: meet it);
//   - the CPU BVH2 traversal gives the CPU CWBVH traversal's hits (closest: t
//     bitwise and hit/miss; any: hit/miss), differences only where the oracle
//     says both are right;
//   - the same tree re-expanded into a legacy BVH2 section (one record per leaf)
//     validates and traces to bitwise the same hits;
//   - the lane steps of bvh2_lane.h run as a lock-step 32-lane warp under the
//     kernel's rules (speculative traversal, leaf postponing, dynamic fetch) give
//     the single-lane CPU reference's hits bit for bit.
// Scenes: generated meshes, and the Stanford bunny from ../shared/scenes (skipped
// when the corpus is absent).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <random>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/format/scene_data.h"
#include "cwbvh/format/tree_depth.h"
#include "cwbvh/format/writer.h"
#include "cwbvh/kernels/bvh2_lane.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/warp_model.h"
#include "scene_corpus.h"
#include "stress/stress_support.h"

namespace cwbvh::stress {
namespace {

using test::Mesh;

struct Box {
    float lo[3], hi[3];
};
Box child_box(const Bvh2Node& n, int c) {
    return c == 0 ? Box{{n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z}}
                  : Box{{n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z}};
}

/// Leaf ranges tile TRIS; leaf triangles lie in (split references: meet) their box.
void expect_leaf_ranges_tile_tris(const File& f) {
    ASSERT_EQ(f.bvh2_type(), uint32_t(kSectionBvh2Leaves));
    const auto b = f.bvh2();
    const auto tris = f.triangles();
    std::vector<uint32_t> records_of_prim;
    for (const TriangleRecord& t : tris) {
        if (t.prim >= records_of_prim.size()) records_of_prim.resize(t.prim + 1, 0);
        ++records_of_prim[t.prim];
    }
    std::vector<int> covered(tris.size(), 0);
    uint64_t leaves = 0, records = 0, inside = 0, split = 0;
    for (const Bvh2Node& n : b) {
        for (int c = 0; c < 2; ++c) {
            if (n.child[c] >= 0) continue;
            ++leaves;
            const Box box = child_box(n, c);
            const uint32_t first = uint32_t(~n.child[c]);
            ASSERT_GE(n.leaf_count[c], 1u);
            ASSERT_LE(n.leaf_count[c], uint32_t(kMaxLeafTriangles)) << "cwbvhc's leaves are the wide leaves";
            for (uint32_t k = 0; k < n.leaf_count[c]; ++k) {
                ASSERT_LT(first + k, tris.size());
                ++covered[first + k];
                ++records;
                const TriangleRecord& t = tris[first + k];
                float lo[3], hi[3];
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min({t.v0[a], t.v1[a], t.v2[a]});
                    hi[a] = std::max({t.v0[a], t.v1[a], t.v2[a]});
                }
                bool in = true, meets = true;
                for (int a = 0; a < 3; ++a) {
                    in = in && box.lo[a] <= lo[a] && hi[a] <= box.hi[a];
                    meets = meets && box.lo[a] <= hi[a] && lo[a] <= box.hi[a];
                }
                if (records_of_prim[t.prim] == 1) {
                    EXPECT_TRUE(in) << "record " << first + k << " is outside its leaf box";
                    ++inside;
                } else {
                    EXPECT_TRUE(meets) << "split record " << first + k << " does not meet its leaf box";
                    ++split;
                }
            }
        }
    }
    const bool single_leaf = b.size() == 1 && b[0].child[0] < 0 && b[0].child[0] == b[0].child[1];
    for (size_t t = 0; t < covered.size(); ++t) ASSERT_EQ(covered[t], single_leaf ? 2 : 1) << "record " << t;
    std::printf("  BV2L: %zu nodes, %llu leaves, %.2f records per leaf (%llu whole, %llu split references)\n",
                b.size(), (unsigned long long)leaves, double(records) / double(leaves), (unsigned long long)inside,
                (unsigned long long)split);
}

/// The same tree as a legacy BVH2 section: a leaf of k records becomes a chain of
/// k - 1 nodes appended at the end whose children all have the leaf's box, so the
/// traversal tests the same records in the same order.
std::vector<Bvh2Node> expand_to_legacy(std::span<const Bvh2Node> ranges) {
    std::vector<Bvh2Node> out(ranges.begin(), ranges.end());
    const size_t original = out.size();
    for (size_t i = 0; i < original; ++i) {
        for (int c = 0; c < 2; ++c) {
            const uint32_t count = out[i].leaf_count[c];
            out[i].leaf_count[c] = 0;
            if (out[i].child[c] >= 0 || count <= 1) continue;
            const int32_t first = ~out[i].child[c];
            const Box box = child_box(out[i], c);
            out[i].child[c] = int32_t(out.size());  // the chain's first node
            for (uint32_t k = 0; k + 1 < count; ++k) {
                const int32_t index = int32_t(out.size());
                Bvh2Node n{box.lo[0], box.hi[0], box.lo[1], box.hi[1], box.lo[0], box.hi[0], box.lo[1], box.hi[1],
                           box.lo[2], box.hi[2], box.lo[2], box.hi[2], {~(first + int32_t(k)), 0}, {0, 0}};
                n.child[1] = k + 2 == count ? ~(first + int32_t(k) + 1) : index + 1;
                out.push_back(n);
            }
        }
    }
    return out;
}

/// A file with the opened file's NODE/TRIS/PMAP/BNDS and a legacy BVH2 section.
std::vector<uint8_t> legacy_file(const File& f, const std::vector<Bvh2Node>& legacy) {
    Writer w;
    w.add_array<CwbvhNode>(kSectionNodes, kSectionRequired, f.nodes());
    w.add_array<TriangleRecord>(kSectionTriangles, kSectionRequired, f.triangles());
    w.add_array<SourceRange>(kSectionSourceMap, kSectionRequired, f.source_ranges());
    w.add_array<SceneBounds>(kSectionBounds, kSectionRequired, std::span<const SceneBounds>(f.bounds(), 1));
    w.add_array<Bvh2Node>(kSectionBvh2, 0, legacy);
    std::vector<uint8_t> out;
    EXPECT_TRUE(w.to_bytes(out).ok());
    return out;
}

bool same_hit(const Hit& a, const Hit& b) { return std::memcmp(&a, &b, sizeof(Hit)) == 0; }

template <TriangleTest kTest, HitMode kMode>
void expect_warp_matches_reference(const std::string& name, std::span<const Bvh2Node> b,
                                   std::span<const TriangleRecord> tris, const std::vector<Ray>& rays) {
    std::vector<Hit> ref(rays.size()), warp;
    std::vector<TraceStatus> ref_status(rays.size());
    CpuTraceOptions o;
    o.test = kTest;
    o.mode = kMode;
    o.threads = 2;
    o.statuses = ref_status.data();
    std::vector<TraceCounters> counters(rays.size());
    o.counters = counters.data();
    trace_bvh2_cpu(b.data(), b.size(), tris.data(), tris.size(), rays.data(), ref.data(), rays.size(), o);
    // The kernel's warp loop (traverse_gpu_bvh2.h, documented in bvh2_lane.h) on the
    // CPU: the warp model's 32 lanes in lock step over the lane steps.
    WarpModelOptions wo;
    wo.test = kTest;
    wo.mode = kMode;
    wo.warps = 8;
    warp.assign(rays.size(), Hit{});
    const WarpModelStats w =
        model_bvh2_warps(b.data(), b.size(), tris.data(), tris.size(), rays.data(), warp.data(), rays.size(), wo);
    uint64_t differ = 0, single_lane_steps = 0, ref_overflows = 0, ref_bad = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        differ += !same_hit(ref[i], warp[i]);
        single_lane_steps += counters[i].nodes;
        ref_overflows += ref_status[i] == TraceStatus::kStackOverflow;
        ref_bad += ref_status[i] == TraceStatus::kBadIndex;
    }
    EXPECT_EQ(differ, 0u) << name;
    EXPECT_EQ(w.stack_overflows, ref_overflows) << name;
    EXPECT_EQ(w.bad_indices, ref_bad) << name;
    // Speculative traversal visits at least the nodes a lone lane visits.
    EXPECT_GE(w.lane_node_steps, single_lane_steps) << name;
    std::printf("  warp model %s %s %s: %zu rays, %llu differ; node steps/ray %.2f (lone lane %.2f), "
                "warp node steps %llu, tri steps %llu, fetches %llu\n",
                name.c_str(), kTest == TriangleTest::kFast ? "fast" : "watertight",
                kMode == HitMode::kAny ? "any" : "closest", rays.size(), (unsigned long long)differ,
                double(w.lane_node_steps) / double(rays.size()), double(single_lane_steps) / double(rays.size()),
                (unsigned long long)w.warp_node_steps, (unsigned long long)w.warp_tri_steps,
                (unsigned long long)w.refills);
}

void check_compiled(const std::string& name, const File& f, const std::vector<Ray>& rays) {
    SCOPED_TRACE(name);
    expect_leaf_ranges_tile_tris(f);
    const auto nodes = f.nodes();
    const auto tris = f.triangles();
    const auto b = f.bvh2();
    const size_t n = rays.size();
    const CulledOracle oracle(tris);
    // CPU BVH2 vs CPU CWBVH: closest (both tests) and any.
    for (const TriangleTest test : {TriangleTest::kWatertight, TriangleTest::kFast}) {
        for (const HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
            std::vector<Hit> cw(n), b2(n);
            std::vector<TraceStatus> st(n);
            CpuTraceOptions o;
            o.test = test;
            o.mode = mode;
            o.threads = 2;
            trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), rays.data(), cw.data(), n, o);
            o.statuses = st.data();
            trace_bvh2_cpu(b.data(), b.size(), tris.data(), tris.size(), rays.data(), b2.data(), n, o);
            uint64_t differ = 0, unexplained = 0, not_ok = 0;
            for (size_t i = 0; i < n; ++i) {
                not_ok += st[i] != TraceStatus::kOk;
                const bool same_hit_miss = (cw[i].prim == kMissPrim) == (b2[i].prim == kMissPrim);
                const bool same = same_hit_miss && (mode == HitMode::kAny || std::memcmp(&cw[i].t, &b2[i].t, 4) == 0);
                if (same) continue;
                ++differ;
                // A triangle test may report a hit a rounding error outside the triangle's
                // box; the trees' boxes differ (BV2L exact, NODE quantized), so one may cull
                // it. Both answers must then be right (fast test: reported only).
                const test::OracleResult ex = oracle.trace(rays[i]);
                Tally x, y;
                if (mode == HitMode::kAny) {
                    classify_any(rays[i], cw[i], ex, oracle, x);
                    classify_any(rays[i], b2[i], ex, oracle, y);
                } else {
                    classify_closest(rays[i], cw[i], ex, oracle, x);
                    classify_closest(rays[i], b2[i], ex, oracle, y);
                }
                unexplained += !x.clean() || !y.clean();
            }
            std::printf("  %s bvh2 vs cwbvh %s %s: %zu rays, %llu differ, %llu unexplained\n", name.c_str(),
                        test == TriangleTest::kFast ? "fast" : "watertight",
                        mode == HitMode::kAny ? "any" : "closest", n, (unsigned long long)differ,
                        (unsigned long long)unexplained);
            EXPECT_EQ(not_ok, 0u);
            if (test == TriangleTest::kWatertight) {
                EXPECT_EQ(unexplained, 0u);
            }
            EXPECT_LE(differ, n / 1000 + 2);
        }
    }
    // The same tree as a legacy BVH2 file: validates, loads, traces to the same hits.
    const std::vector<Bvh2Node> legacy = expand_to_legacy(b);
    ASSERT_LE(bvh2_tree_depth(legacy), kMaxBvh2Depth);
    const std::vector<uint8_t> bytes = legacy_file(f, legacy);
    FileLayout layout;
    const Result r = validate(bytes, {}, &layout);
    ASSERT_TRUE(r.ok()) << r.describe();
    EXPECT_EQ(layout.header.version_minor, 0u);
    for (const HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        std::vector<Hit> h1(n), h0(n);
        CpuTraceOptions o;
        o.mode = mode;
        o.threads = 2;
        trace_bvh2_cpu(b.data(), b.size(), tris.data(), tris.size(), rays.data(), h1.data(), n, o);
        trace_bvh2_cpu(legacy.data(), legacy.size(), tris.data(), tris.size(), rays.data(), h0.data(), n, o);
        uint64_t differ = 0;
        for (size_t i = 0; i < n; ++i) differ += !same_hit(h1[i], h0[i]);
        EXPECT_EQ(differ, 0u) << "legacy BVH2 " << (mode == HitMode::kAny ? "any" : "closest");
    }
    // The kernel's warp rules over the lane steps, against the single-lane reference.
    expect_warp_matches_reference<TriangleTest::kWatertight, HitMode::kClosest>(name, b, tris, rays);
    expect_warp_matches_reference<TriangleTest::kWatertight, HitMode::kAny>(name, b, tris, rays);
    expect_warp_matches_reference<TriangleTest::kFast, HitMode::kClosest>(name, b, tris, rays);
    expect_warp_matches_reference<TriangleTest::kWatertight, HitMode::kClosest>(name + "-legacy", legacy, tris, rays);
}

class Bvh2LeafRanges : public TempDirSuite {};

TEST_F(Bvh2LeafRanges, GeneratedScenes) {
    struct Case {
        const char* name;
        Mesh mesh;
    };
    std::vector<Case> cases;
    cases.push_back({"grid", test::grid_mesh(40)});
    cases.push_back({"sphere", test::cube_mesh(16, true)});
    {
        // A soup of overlapping triangles of mixed sizes: spatial splits happen.
        Mesh soup;
        std::mt19937 rng(3);
        std::uniform_real_distribution<float> u(0.0f, 100.0f);
        for (uint32_t i = 0; i < 3000; ++i) {
            const float size = i % 10 == 0 ? 40.0f : 3.0f;
            const float c[3] = {u(rng), u(rng), u(rng)};
            for (int k = 0; k < 3; ++k)
                for (int a = 0; a < 3; ++a) soup.v.push_back(c[a] + (u(rng) / 100.0f - 0.5f) * size);
            for (uint32_t k = 0; k < 3; ++k) soup.idx.push_back(3 * i + k);
        }
        cases.push_back({"soup", soup});
    }
    for (const Case& c : cases) {
        File f;
        std::string err;
        ASSERT_TRUE(compile_and_open(write_obj(c.mesh, c.name), c.name, f, err)) << err;
        check_compiled(c.name, f, scene_rays(f, 3000, 48, 11));
    }
}

TEST_F(Bvh2LeafRanges, Bunny) {
    const std::string path = ::cwbvh::test::corpus_scene("bunny.obj");
    CWBVH_REQUIRE_SCENE(path);
    File f;
    std::string err;
    ASSERT_TRUE(compile_and_open(path, "bunny-bv2l", f, err)) << err;
    check_compiled("bunny", f, scene_rays(f, 4000, 96, 5));
}

TEST_F(Bvh2LeafRanges, LegacySyntheticFileTraces) {
    // A 1.0 file with a BVH2 section (one record per leaf, leaf_count 0) as the
    // synthetic generator and cwbvhc 1.0 wrote them: it validates, File::bvh2()
    // hands it out, and it traces like the wide tree.
    SyntheticOptions o;
    o.triangles = 500;
    const SceneData scene = make_synthetic_scene(o);
    Writer w;
    add_scene_sections(w, scene);
    const std::string path = (temp_dir() / "legacy.cwbvh").string();
    ASSERT_TRUE(w.write_file(path).ok());
    auto f = File::open(path);
    ASSERT_TRUE(f.ok()) << f.error().describe();
    EXPECT_EQ(f->header().version_minor, 0u);
    EXPECT_EQ(f->bvh2_type(), uint32_t(kSectionBvh2));
    ASSERT_EQ(f->bvh2().size(), scene.bvh2.size());
    const std::vector<Ray> rays = scene_rays(*f, 3000, 32, 9);
    std::vector<Hit> cw(rays.size()), b2(rays.size());
    trace_cwbvh_cpu(f->nodes().data(), f->nodes().size(), f->triangles().data(), f->triangles().size(), rays.data(),
                    cw.data(), rays.size());
    const CpuTraceStats s = trace_bvh2_cpu(f->bvh2().data(), f->bvh2().size(), f->triangles().data(),
                                           f->triangles().size(), rays.data(), b2.data(), rays.size());
    EXPECT_EQ(s.bad_indices + s.stack_overflows + s.invalid_rays, 0u);
    uint64_t differ = 0;
    for (size_t i = 0; i < rays.size(); ++i)
        differ += (cw[i].prim == kMissPrim) != (b2[i].prim == kMissPrim) || std::memcmp(&cw[i].t, &b2[i].t, 4) != 0;
    EXPECT_LE(differ, rays.size() / 1000 + 1);
    expect_warp_matches_reference<TriangleTest::kWatertight, HitMode::kClosest>("synthetic-legacy", f->bvh2(),
                                                                                f->triangles(), rays);
}

TEST(Bvh2Lane, PackedLeavesAndBadIndices) {
    // Two records in one leaf, a bad internal index, a range past TRIS.
    const TriangleRecord tris[3] = {{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0},
                                    {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}, 1},
                                    {{0, 0, 2}, {1, 0, 2}, {0, 1, 2}, 2}};
    Bvh2Node root{0, 1, 0, 1, 0, 1, 0, 1, 0, 1, 2, 2, {~0, ~2}, {2, 1}};
    const Ray down{{0.25f, 0.25f, 5.0f}, 0.0f, {0.0f, 0.0f, -1.0f}, kInfinity};
    Hit h;
    TraceCounters c{};
    EXPECT_EQ((traverse_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(&root, 1, tris, 3, down, h, &c)),
              TraceStatus::kOk);
    EXPECT_EQ(h.prim, 2u);
    EXPECT_EQ(h.t, 3.0f);
    EXPECT_EQ(c.triangles, 3u);
    // From below, any hit: the first record tested is the nearer leaf's first.
    const Ray up{{0.25f, 0.25f, -5.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, kInfinity};
    EXPECT_EQ((traverse_bvh2<TriangleTest::kWatertight, HitMode::kAny>(&root, 1, tris, 3, up, h, &c)),
              TraceStatus::kOk);
    EXPECT_EQ(h.prim, 0u);
    EXPECT_EQ(c.triangles, 1u);
    Bvh2Node bad = root;
    bad.leaf_count[0] = 3;  // records 0..2 fine; count 3 with first 1 runs past TRIS
    bad.child[0] = ~1;
    EXPECT_EQ((traverse_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(&bad, 1, tris, 3, down, h)),
              TraceStatus::kBadIndex);
    bad = root;
    bad.leaf_count[0] = 5;  // more than a packed leaf holds
    EXPECT_EQ((traverse_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(&bad, 1, tris, 3, down, h)),
              TraceStatus::kBadIndex);
    bad = root;
    bad.child[1] = 7;  // internal child outside the array
    bad.leaf_count[1] = 0;
    EXPECT_EQ((traverse_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(&bad, 1, tris, 3, down, h)),
              TraceStatus::kBadIndex);
    // Legacy leaves (count 0 = one record) and the unpacked form for TRIS > 2^29.
    Bvh2Node legacy = root;
    legacy.leaf_count[0] = legacy.leaf_count[1] = 0;
    EXPECT_EQ((traverse_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(&legacy, 1, tris, 3, down, h, &c)),
              TraceStatus::kOk);
    EXPECT_EQ(h.prim, 2u);
    EXPECT_EQ(c.triangles, 2u);
    Bvh2Scene s = make_bvh2_scene(&legacy, 1, tris, 3);
    EXPECT_EQ(s.leaf_bits, 2u);
    EXPECT_EQ(make_bvh2_scene(&legacy, 1, tris, kBvh2PackedTrisLimit + 1).leaf_bits, 0u);
    s.leaf_bits = 0;  // as for a legacy file of more than 2^29 records
    int32_t w = 0;
    ASSERT_TRUE(bvh2_child_word(~2, 0, s, w));
    EXPECT_EQ(w, ~2);
    EXPECT_FALSE(bvh2_child_word(~0, 2, s, w)) << "no room for a count";
    Bvh2Lane<TriangleTest::kWatertight> l;
    Bvh2LaneMemory m;
    ASSERT_TRUE(bvh2_lane_start(l, m, down, s));
    while (!bvh2_lane_done(l)) {
        while (bvh2_lane_in_nodes(l) && !bvh2_lane_has_leaf(l)) bvh2_lane_node_step(l, m, s);
        while (bvh2_lane_has_leaf(l)) bvh2_lane_triangle_step<HitMode::kClosest>(l, m, s);
    }
    EXPECT_EQ(l.status, TraceStatus::kOk);
    EXPECT_EQ(bvh2_lane_hit(l, m).prim, 2u);
}

}  // namespace
}  // namespace cwbvh::stress
