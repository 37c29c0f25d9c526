// The kernels' bodies (traverse_gpu.h trace_cwbvh_persistent, traverse_gpu_bvh2.h
// trace_bvh2_persistent) run on the CPU by kernel_emulation.h: CUDA threads as
// fibers, warp votes and shuffles as meeting points of the warp's 32 lanes. With one
// warp a kernel must do exactly what the warp model (warp_model.h) does with one warp:
// same rays in the same lanes, same postponing, so the same hits bit for bit, the
// same statuses and the same node and triangle counts. Issue 18: the kernel's warp control changes without a GPU at hand; these
// tests run it. Device-only branches (#if __CUDA_ARCH__) are not covered here (see
// kernel_emulation.h).
#include "model/kernel_emulation.h"  // first: defines what the kernel headers need

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <vector>

#include "cwbvh/compiler/core.h"
#include "cwbvh/compiler/emit.h"
#include "cwbvh/kernels/traverse_gpu.h"
#include "cwbvh/kernels/traverse_gpu_bvh2.h"
#include "cwbvh/kernels/warp_model.h"
#include "model/model_fixture.h"

namespace cwbvh {
namespace {

using model_test::expect_same_hits;
using model_test::Fixture;
using model_test::reference;

/// 5,000 triangles, 40 x 40 camera rays and their bounce: every warp vote is 32 fiber
/// switches, so the emulated kernels get fewer rays than the warp model's tests.
const Fixture& fixture() {
    static const Fixture f = model_test::make_fixture(5000, 40);
    return f;
}

struct KernelRun {
    std::vector<Hit> hits;
    std::vector<TraceStatus> status;
    gpu::WorkArea work{};
};

template <TriangleTest kTest, HitMode kMode, bool kCount, bool kDefer>
void launch(const gpu::LaunchParams& p, unsigned threads) {
    cwbvh_emulation::run_block(threads, [&] {
        // The kernel's shared stack (kernels_cwbvh.cu): [warp][entry][lane].
        static PackedEntry s_stack[gpu::kCwbvhWarpsPerBlock][kGpuSharedStackEntries][gpu::kWarpSize];
        gpu::trace_cwbvh_persistent<kTest, kMode, kCount, kDefer>(p, &s_stack[threadIdx.x / gpu::kWarpSize][0][0]);
    });
}

/// defer: the kernel's deferred hit distances (kernels_cwbvh.cu's production kernels), or
/// the kernel without them (TraceOptions::defer_hits = false).
template <TriangleTest kTest, HitMode kMode>
void launch(const gpu::LaunchParams& p, unsigned threads, bool count, bool defer) {
    if (count && defer)
        launch<kTest, kMode, true, true>(p, threads);
    else if (count)
        launch<kTest, kMode, true, false>(p, threads);
    else if (defer)
        launch<kTest, kMode, false, true>(p, threads);
    else
        launch<kTest, kMode, false, false>(p, threads);
}

/// A launch's rays, triangles and outputs (r's arrays filled with values no kernel
/// writes); the caller sets the tree.
gpu::LaunchParams launch_params(const Fixture& f, KernelRun& r) {
    r.hits.assign(f.rays.size(), Hit{-1.0f, -1.0f, -1.0f, 12345u});
    r.status.assign(f.rays.size(), TraceStatus(0xEEu));
    gpu::LaunchParams p{};
    p.tris = f.scene.triangles.data();
    p.tri_count = uint32_t(f.scene.triangles.size());
    p.rays = f.rays.data();
    p.hits = r.hits.data();
    p.status = r.status.data();
    p.ray_count = uint32_t(f.rays.size());
    p.work = &r.work;
    return p;
}

/// One launch of the kernel body over `nodes` (one block of `warps` warps: the kernel's
/// persistent loop takes every ray), with the scene constants the device upload computes.
KernelRun run_kernel(const std::vector<CwbvhNode>& nodes, const Fixture& f, TriangleTest test, HitMode mode,
                     bool count, unsigned warps = 1, bool defer = true, int postpone = kPostponePercent,
                     bool fast_node_test = true) {
    KernelRun r;
    gpu::LaunchParams p = launch_params(f, r);
    p.postpone_percent = uint32_t(postpone);
    p.nodes = nodes.data();
    p.node_count = uint32_t(nodes.size());
    // trace(): TraceOptions::fast_node_test = false passes NodeScale{} (usable 0).
    p.node_scale = fast_node_test ? node_scale(nodes.data(), nodes.size()) : NodeScale{};
    const unsigned threads = warps * unsigned(gpu::kWarpSize);
    if (test == TriangleTest::kWatertight) {
        if (mode == HitMode::kClosest)
            launch<TriangleTest::kWatertight, HitMode::kClosest>(p, threads, count, defer);
        else
            launch<TriangleTest::kWatertight, HitMode::kAny>(p, threads, count, defer);
    } else {
        if (mode == HitMode::kClosest)
            launch<TriangleTest::kFast, HitMode::kClosest>(p, threads, count, defer);
        else
            launch<TriangleTest::kFast, HitMode::kAny>(p, threads, count, defer);
    }
    return r;
}

/// The warp model with one warp: the emulated one-warp kernel's schedule.
WarpModelStats run_model(const std::vector<CwbvhNode>& nodes, const Fixture& f, TriangleTest test, HitMode mode,
                         std::vector<Hit>& hits, bool defer = true, int postpone = kPostponePercent,
                         bool fast_node_test = true) {
    WarpModelOptions o;
    o.fast_node_test = fast_node_test;
    o.mode = mode;
    o.test = test;
    o.warps = 1;
    o.defer_hits = defer;
    o.postpone_percent = postpone;
    hits.assign(f.rays.size(), Hit{-1.0f, -1.0f, -1.0f, 12345u});
    return model_cwbvh_warps(nodes.data(), nodes.size(), f.scene.triangles.data(), f.scene.triangles.size(),
                             f.rays.data(), hits.data(), f.rays.size(), o);
}

void expect_bitwise_equal(const std::vector<Hit>& got, const std::vector<Hit>& want) {
    ASSERT_EQ(got.size(), want.size());
    size_t bad = 0;
    for (size_t i = 0; i < want.size(); ++i)
        if (std::memcmp(&got[i], &want[i], sizeof(Hit)) != 0 && ++bad <= 3)
            ADD_FAILURE() << "ray " << i << ": kernel prim " << got[i].prim << " t " << got[i].t << ", model prim "
                          << want[i].prim << " t " << want[i].t;
    EXPECT_EQ(bad, 0u);
}

size_t count_status(const std::vector<TraceStatus>& s, TraceStatus which) {
    size_t n = 0;
    for (TraceStatus x : s) n += x == which;
    return n;
}

TEST(KernelEmulation, CwbvhKernelAnswersAsTheWarpModelBitForBit) {
    const Fixture& f = fixture();
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        for (TriangleTest test : {TriangleTest::kWatertight, TriangleTest::kFast}) {
            std::vector<Hit> model_hits;
            const WarpModelStats s = run_model(f.scene.nodes, f, test, mode, model_hits);
            for (bool count : {false, true}) {
                SCOPED_TRACE(testing::Message() << "mode " << int(mode) << " test " << int(test) << " count " << count);
                const KernelRun k = run_kernel(f.scene.nodes, f, test, mode, count);
                expect_bitwise_equal(k.hits, model_hits);
                EXPECT_EQ(k.work.next_ray >= f.rays.size(), true) << "every ray was fetched";
                EXPECT_EQ(k.work.invalid, 1u);
                EXPECT_EQ(count_status(k.status, TraceStatus::kInvalidRay), 1u);
                EXPECT_EQ(count_status(k.status, TraceStatus::kOk), f.rays.size() - 1);
                EXPECT_EQ(k.work.overflows + k.work.bad_indices, 0u);
                if (count) {
                    EXPECT_EQ(k.work.nodes, s.lane_node_steps) << "the same node steps as the model";
                    EXPECT_EQ(k.work.triangles, s.lane_tri_tests) << "the same triangle tests as the model";
                } else {
                    EXPECT_EQ(k.work.nodes + k.work.triangles, 0u) << "the production variant counts nothing";
                }
            }
        }
    }
}

TEST(KernelEmulation, FourWarpsOfABlockGiveTheReferenceHits) {
    const Fixture& f = fixture();
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        SCOPED_TRACE(testing::Message() << "mode " << int(mode));
        const KernelRun k = run_kernel(f.scene.nodes, f, TriangleTest::kWatertight, mode, false,
                                       unsigned(gpu::kCwbvhWarpsPerBlock));
        expect_same_hits(k.hits, reference(f, mode, TriangleTest::kWatertight), mode);
        EXPECT_EQ(count_status(k.status, TraceStatus::kOk), f.rays.size() - 1);
    }
}

/// A flat 8 x 8 grid of quads, two exact duplicates of it and two coplanar copies shifted by
/// fractions of a cell: hits at equal or nearly equal t, where the float bounds of a deferred
/// hit overlap the next candidate's and the kernel takes its rare paths (a deferred hit
/// finished inside a triangle round, the candidate tested again in the next round).
/// Rays: camera rays from above, at slants.
Fixture coplanar_fixture() {
    compiler::Scene scene;
    const int n = 8;
    for (int c = 0; c < 3; ++c) {
        const uint32_t base = uint32_t(scene.vertices.size());
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i)
                scene.vertices.push_back({float(i) + 0.25f * float(c), float(j) + 0.125f * float(c), 0.0f});
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                const uint32_t a = base + uint32_t(j * (n + 1) + i), b = a + 1, d = a + uint32_t(n + 1), e = d + 1;
                const int copies = c == 0 ? 3 : 1;  // copy 0 three times: exact duplicates
                for (int k = 0; k < copies; ++k) {
                    scene.indices.push_back({a, b, e});
                    scene.indices.push_back({a, e, d});
                }
            }
    }
    for (uint32_t t = 0; t < uint32_t(scene.indices.size()); ++t) scene.sources.push_back({0, 0, t, 0});
    scene.input_triangles = scene.indices.size();
    compiler::CoreOptions core;
    compiler::EmitResult encoded;
    EXPECT_TRUE(compiler::compile_scene(scene, core, encoded).ok());
    Fixture x;
    x.scene = SceneData::copy_of(compiler::scene_sections(scene, encoded));
    const int w = 24;
    for (int j = 0; j < w; ++j)
        for (int i = 0; i < w; ++i) {
            Ray r{};
            r.org[0] = 0.5f + 9.0f * float(i) / float(w);
            r.org[1] = 0.5f + 9.0f * float(j) / float(w);
            r.org[2] = 3.0f;
            r.dir[0] = 0.0625f * float((i % 5) - 2);
            r.dir[1] = 0.03125f * float((j % 7) - 3);
            r.dir[2] = -1.0f;
            r.tmin = 0.0f;
            r.tmax = kInfinity;
            x.rays.push_back(r);
        }
    return x;
}

TEST(KernelEmulation, DeferredHitsOnACoplanarStackAsTheWarpModel) {
    const Fixture f = coplanar_fixture();
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        SCOPED_TRACE(testing::Message() << "mode " << int(mode));
        std::vector<Hit> model_hits;
        const WarpModelStats s = run_model(f.scene.nodes, f, TriangleTest::kWatertight, mode, model_hits);
        const KernelRun k = run_kernel(f.scene.nodes, f, TriangleTest::kWatertight, mode, true);
        expect_bitwise_equal(k.hits, model_hits);
        EXPECT_EQ(k.work.nodes, s.lane_node_steps);
        EXPECT_EQ(k.work.triangles, s.lane_tri_tests);
        expect_same_hits(k.hits, reference(f, mode, TriangleTest::kWatertight), mode);
        EXPECT_EQ(s.finalize_failures, 0u);
        EXPECT_GT(s.lane_deferred_hits, 0u);
        EXPECT_GT(s.lane_finalized, 0u);
        if (mode == HitMode::kClosest) {
            EXPECT_GT(s.lane_prev_finished, 0u) << "a deferred hit finished inside a round";
        }
    }
}

/// The kernel without deferred hit distances (TraceOptions::defer_hits = false, the kernel
/// cwbvh_gpu_check times beside the production one; every kernel before sm_80) against the
/// model without them, on the fixture and on the coplanar stack: the same hits, bit for bit,
/// as the deferring kernel, and the same schedule as the model (node and triangle counts).
TEST(KernelEmulation, KernelWithoutDeferredHitsAsTheWarpModelWithout) {
    for (const bool coplanar : {false, true}) {
        const Fixture f = coplanar ? coplanar_fixture() : fixture();
        for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
            SCOPED_TRACE(testing::Message() << "coplanar " << coplanar << " mode " << int(mode));
            std::vector<Hit> model_hits;
            const WarpModelStats s = run_model(f.scene.nodes, f, TriangleTest::kWatertight, mode, model_hits, false);
            EXPECT_EQ(s.lane_deferred_hits, 0u);
            for (bool count : {false, true}) {
                SCOPED_TRACE(testing::Message() << "count " << count);
                const KernelRun k = run_kernel(f.scene.nodes, f, TriangleTest::kWatertight, mode, count, 1, false);
                expect_bitwise_equal(k.hits, model_hits);
                EXPECT_EQ(count_status(k.status, TraceStatus::kOk) + count_status(k.status, TraceStatus::kInvalidRay),
                          f.rays.size());
                if (count) {
                    EXPECT_EQ(k.work.nodes, s.lane_node_steps);
                    EXPECT_EQ(k.work.triangles, s.lane_tri_tests);
                }
                // Both kernels give the reference's hits (ties at equal t aside: the coplanar stack's
                // duplicates, which the two kernels' different culling and so postponing may
                // test in another order); away from ties the deferral changes no closest hit.
                const KernelRun d = run_kernel(f.scene.nodes, f, TriangleTest::kWatertight, mode, count);
                expect_same_hits(k.hits, reference(f, mode, TriangleTest::kWatertight), mode);
                expect_same_hits(d.hits, reference(f, mode, TriangleTest::kWatertight), mode);
                if (mode == HitMode::kClosest && !coplanar) expect_bitwise_equal(k.hits, d.hits);
            }
        }
    }
}

/// The postponing threshold comes from the launch (TraceOptions::postpone_percent): at 0
/// (never), 35 and 100 (whenever not every lane wants triangles) the kernel schedules as the
/// model with the same threshold, and answers as the reference.
TEST(KernelEmulation, PostponingThresholdFromTheLaunchAsTheWarpModel) {
    const Fixture& f = fixture();
    for (int pc : {0, 35, 100}) {
        SCOPED_TRACE(testing::Message() << "postpone " << pc);
        std::vector<Hit> model_hits;
        const WarpModelStats s =
            run_model(f.scene.nodes, f, TriangleTest::kWatertight, HitMode::kClosest, model_hits, true, pc);
        const KernelRun k = run_kernel(f.scene.nodes, f, TriangleTest::kWatertight, HitMode::kClosest, true, 1, true, pc);
        expect_bitwise_equal(k.hits, model_hits);
        EXPECT_EQ(k.work.nodes, s.lane_node_steps);
        EXPECT_EQ(k.work.triangles, s.lane_tri_tests);
        expect_same_hits(k.hits, reference(f, HitMode::kClosest, TriangleTest::kWatertight), HitMode::kClosest);
        if (pc == 0) {
            EXPECT_EQ(s.postponed, 0u);
        }
    }
}

/// TraceOptions::fast_node_test = false (trace() launches with NodeScale{}): no ray takes the
/// fast node test, and the kernel schedules as the warp model without it, bit for bit, node
/// and triangle counts included; with the scene's constants the model takes it on every ray
/// of the fixture, so the switch changes the path.
TEST(KernelEmulation, ReferenceNodeTestForEveryRayAsTheWarpModelWithout) {
    const Fixture& f = fixture();
    std::vector<Hit> fast_hits;
    const WarpModelStats fast = run_model(f.scene.nodes, f, TriangleTest::kWatertight, HitMode::kClosest, fast_hits);
    EXPECT_GT(fast.lane_fast_node_steps, fast.lane_node_steps / 2);
    std::vector<Hit> model_hits;
    const WarpModelStats s = run_model(f.scene.nodes, f, TriangleTest::kWatertight, HitMode::kClosest, model_hits,
                                       true, kPostponePercent, false);
    EXPECT_EQ(s.lane_fast_node_steps, 0u);
    const KernelRun k = run_kernel(f.scene.nodes, f, TriangleTest::kWatertight, HitMode::kClosest, true, 1, true,
                                   kPostponePercent, false);
    expect_bitwise_equal(k.hits, model_hits);
    EXPECT_EQ(k.work.nodes, s.lane_node_steps);
    EXPECT_EQ(k.work.triangles, s.lane_tri_tests);
    expect_same_hits(k.hits, reference(f, HitMode::kClosest, TriangleTest::kWatertight), HitMode::kClosest);
}

template <TriangleTest kTest, HitMode kMode>
void launch_bvh2(const gpu::LaunchParams& p, bool count) {
    cwbvh_emulation::run_block(gpu::kWarpSize, [&] {
        if (count)
            gpu::trace_bvh2_persistent<kTest, kMode, true>(p);
        else
            gpu::trace_bvh2_persistent<kTest, kMode, false>(p);
    });
}

TEST(KernelEmulation, Bvh2KernelAnswersAsTheWarpModelBitForBit) {
    const Fixture& f = fixture();
    ASSERT_FALSE(f.scene.bvh2.empty());
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        for (TriangleTest test : {TriangleTest::kWatertight, TriangleTest::kFast}) {
            WarpModelOptions o;
            o.mode = mode;
            o.test = test;
            o.warps = 1;
            o.bvh2_kernel = Bvh2Kernel::kAkl2012;  // the kernel's schedule
            std::vector<Hit> model_hits(f.rays.size());
            const WarpModelStats s =
                model_bvh2_warps(f.scene.bvh2.data(), f.scene.bvh2.size(), f.scene.triangles.data(),
                                 f.scene.triangles.size(), f.rays.data(), model_hits.data(), f.rays.size(), o);
            for (bool count : {false, true}) {
                SCOPED_TRACE(testing::Message() << "mode " << int(mode) << " test " << int(test) << " count " << count);
                KernelRun k;
                gpu::LaunchParams p = launch_params(f, k);
                p.bvh2 = f.scene.bvh2.data();
                p.node_count = uint32_t(f.scene.bvh2.size());
                if (test == TriangleTest::kWatertight) {
                    if (mode == HitMode::kClosest)
                        launch_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(p, count);
                    else
                        launch_bvh2<TriangleTest::kWatertight, HitMode::kAny>(p, count);
                } else {
                    if (mode == HitMode::kClosest)
                        launch_bvh2<TriangleTest::kFast, HitMode::kClosest>(p, count);
                    else
                        launch_bvh2<TriangleTest::kFast, HitMode::kAny>(p, count);
                }
                expect_bitwise_equal(k.hits, model_hits);
                EXPECT_EQ(k.work.invalid, 1u);
                EXPECT_EQ(count_status(k.status, TraceStatus::kInvalidRay), 1u);
                EXPECT_EQ(count_status(k.status, TraceStatus::kOk), f.rays.size() - 1);
                EXPECT_EQ(k.work.nodes, count ? s.lane_node_steps : 0u);
                EXPECT_EQ(k.work.triangles, count ? s.lane_tri_tests : 0u);
            }
        }
    }
}

/// A chain of `count` nodes, each with two internal children over the same box, node i's
/// at i + 1 and i + 2 (the last two nodes are empty): a ray through the box takes one
/// child and pushes the other at every level, so the stack needs about count / 2
/// entries, more than the kernel's 64 (kGpuStackEntries) for count = 200. No cycle:
/// every ray ends.
std::vector<CwbvhNode> deep_chain(uint32_t count) {
    std::vector<CwbvhNode> nodes(count);
    for (uint32_t i = 0; i < count; ++i) {
        CwbvhNode& n = nodes[i];
        std::memset(&n, 0, sizeof n);
        n.e[0] = n.e[1] = n.e[2] = 127 - 8;  // scale 2^-8: the box [0, 255/256]^3
        if (i + 2 >= count) continue;        // empty node
        n.imask = 0x03;
        n.child_base = i + 1;
        for (int s = 0; s < 2; ++s) {
            n.meta[s] = uint8_t(0x20 | (24 + s));
            for (int a = 0; a < 3; ++a) n.q_hi[a][s] = 255;
        }
    }
    return nodes;
}

TEST(KernelEmulation, CorruptTreesEndRaysAsTheWarpModelDoes) {
    const Fixture& f = fixture();
    // (a) children past NODE: kBadIndex, with the closest hit found before;
    // (b) a tree deeper than the stack: kStackOverflow (the fixture's rays, over a deep
    //     chain in the unit cube that the fixture's scene does not reach: the rays that
    //     cross the cube overflow; rays that miss it end with a miss).
    size_t corrupt = f.scene.nodes.size();
    for (size_t i = f.scene.nodes.size(); i-- > 1;)
        if (f.scene.nodes[i].imask != 0) {
            corrupt = i;
            break;
        }
    ASSERT_LT(corrupt, f.scene.nodes.size());
    std::vector<CwbvhNode> bad_index = f.scene.nodes;
    bad_index[corrupt].child_base = 0x7FFFFFF0u;
    std::vector<CwbvhNode> deep = deep_chain(200);
    Fixture into_cube = f;  // the same rays aimed through the cube
    for (size_t i = 0; i < into_cube.rays.size(); ++i) {
        Ray& r = into_cube.rays[i];
        if (!ray_is_traceable(r)) continue;
        const float o[3] = {0.5f, 0.5f, 0.5f};
        for (int a = 0; a < 3; ++a) r.org[a] = o[a] - 2.0f * r.dir[a];
        r.tmin = 0.0f;
        r.tmax = i % 7 == 0 ? 1.0f : kInfinity;  // some rays end before the cube
    }
    for (const std::vector<CwbvhNode>* nodes : {&bad_index, &deep}) {
        const bool is_deep = nodes == &deep;
        const Fixture& rays = is_deep ? into_cube : f;
        SCOPED_TRACE(is_deep ? "deep" : "bad index");
        std::vector<Hit> model_hits;
        const WarpModelStats s = run_model(*nodes, rays, TriangleTest::kWatertight, HitMode::kClosest, model_hits);
        const KernelRun k = run_kernel(*nodes, rays, TriangleTest::kWatertight, HitMode::kClosest, true);
        expect_bitwise_equal(k.hits, model_hits);
        EXPECT_EQ(k.work.bad_indices, s.bad_indices);
        EXPECT_EQ(k.work.overflows, s.stack_overflows);
        EXPECT_EQ(count_status(k.status, TraceStatus::kBadIndex), s.bad_indices);
        EXPECT_EQ(count_status(k.status, TraceStatus::kStackOverflow), s.stack_overflows);
        EXPECT_EQ(k.work.nodes, s.lane_node_steps);
        EXPECT_EQ(k.work.triangles, s.lane_tri_tests);
        EXPECT_GT(is_deep ? s.stack_overflows : s.bad_indices, 0u) << "the corruption is reached";
        if (is_deep) {
            // The CPU reference agrees ray by ray (no triangles: postponing cannot matter).
            std::vector<Hit> ref(rays.rays.size());
            std::vector<TraceStatus> ref_status(rays.rays.size());
            CpuTraceOptions co;
            co.threads = 1;
            co.statuses = ref_status.data();
            trace_cwbvh_cpu(nodes->data(), nodes->size(), rays.scene.triangles.data(), rays.scene.triangles.size(),
                            rays.rays.data(), ref.data(), rays.rays.size(), co);
            EXPECT_EQ(k.status, ref_status);
            EXPECT_LT(s.stack_overflows, rays.rays.size() - 1) << "the rays that end before the cube do not overflow";
        }
    }
}

}  // namespace
}  // namespace cwbvh
