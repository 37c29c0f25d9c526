// The two-level GPU variant (kernels/src/trace_two_level.cu): its per-thread code
// is traverse_two_level.h with the kernel's stack (gpu_stack.h), so the CPU runs it
// too (first test, always). With a CUDA device, the kernel's hits must equal the
// CPU reference's bit for bit (t, u, v, prim, instance; closest and any hit; the
// statistics variant's counters equal the CPU's); without one the GPU tests skip.
#include <gtest/gtest.h>

#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "kernels_test_util.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/gpu_stack.h"
#include "cwbvh/kernels/gpu_trace.h"
#if defined(CWBVH_HAVE_CUDA)
#include <cuda_runtime.h>

#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/kernels/trace.h"
#endif

namespace cwbvh::test {
namespace {

TwoLevelBuild scene() { return instanced_test_scene(21, 300); }

std::vector<Ray> rays_for(const TwoLevelBuild& b, size_t n) {
    std::mt19937 rng(22);
    std::uniform_real_distribution<float> u(-5.0f, 45.0f);
    std::vector<Ray> rays;
    for (size_t i = 0; i < n; ++i) {
        const float o[3] = {u(rng), u(rng), u(rng)}, t[3] = {u(rng), u(rng), u(rng)};
        const float d[3] = {t[0] - o[0], t[1] - o[1], t[2] - o[2]};
        rays.push_back(make_ray(o, d));
    }
    (void)b;
    return rays;
}

TEST(TwoLevelGpuPath, KernelStackGivesTheReferenceHits) {
    // The kernel's per-thread path (GpuStack: 12 shared entries, then local) on the
    // CPU, against the CPU reference's LocalStack: same hits and statuses.
    const TwoLevelBuild b = scene();
    const std::vector<Ray> rays = rays_for(b, 4000);
    std::vector<PackedEntry> shared(size_t(kGpuSharedStackEntries) * 32);
    size_t hits = 0;
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        for (const Ray& r : rays) {
            Hit h1, h2;
            uint32_t i1 = 0, i2 = 0;
            LocalStack<kCpuStackSize> ls;
            PackedEntry spill[kGpuLocalStackEntries];
            GpuStack gs(shared.data() + 7, spill);
            const TraceStatus s1 =
                mode == HitMode::kAny
                    ? traverse_two_level<TriangleTest::kWatertight, HitMode::kAny>(b.view(), r, h1, i1, ls)
                    : traverse_two_level<TriangleTest::kWatertight, HitMode::kClosest>(b.view(), r, h1, i1, ls);
            const TraceStatus s2 =
                mode == HitMode::kAny
                    ? traverse_two_level<TriangleTest::kWatertight, HitMode::kAny>(b.view(), r, h2, i2, gs)
                    : traverse_two_level<TriangleTest::kWatertight, HitMode::kClosest>(b.view(), r, h2, i2, gs);
            ASSERT_EQ(s1, s2);
            ASSERT_EQ(std::memcmp(&h1, &h2, sizeof h1), 0);
            ASSERT_EQ(i1, i2);
            hits += h1.prim != kMissPrim;
        }
    }
    EXPECT_GT(hits, rays.size() / 5);
}

#if defined(CWBVH_HAVE_CUDA)
TEST(TwoLevelGpu, HitsEqualTheCpuReferenceBitForBit) {
    if (!have_gpu()) GTEST_SKIP() << "no CUDA device";
    const TwoLevelBuild b = scene();
    const std::vector<Ray> rays = rays_for(b, 50000);
    const TwoLevelSections t = top_level_sections(b);
    Expected<DeviceScene> ds =
        DeviceScene::upload(b.nodes.data(), b.nodes.size(), b.tris.data(), b.tris.size(), nullptr, 0, t);
    ASSERT_TRUE(ds.ok()) << ds.error().message;
    ASSERT_TRUE(ds->has_two_level());
    const size_t n = rays.size();
    Ray* d_rays = nullptr;
    Hit* d_hits = nullptr;
    uint32_t* d_inst = nullptr;
    ASSERT_EQ(cudaMalloc(&d_rays, n * sizeof(Ray)), cudaSuccess);
    ASSERT_EQ(cudaMalloc(&d_hits, n * sizeof(Hit)), cudaSuccess);
    ASSERT_EQ(cudaMalloc(&d_inst, n * sizeof(uint32_t)), cudaSuccess);
    ASSERT_EQ(cudaMemcpy(d_rays, rays.data(), n * sizeof(Ray), cudaMemcpyHostToDevice), cudaSuccess);
    for (Query q : {Query::kClosest, Query::kAny}) {
        CpuTraceOptions o;
        o.mode = q == Query::kAny ? HitMode::kAny : HitMode::kClosest;
        std::vector<Hit> ch(n);
        std::vector<uint32_t> ci(n);
        const CpuTraceStats cs = trace_two_level_cpu(b.view(), rays.data(), ch.data(), ci.data(), n, o);
        DeviceTraceStats gs;
        TraceOptions to;
        to.stats = &gs;
        trace_two_level(ds.value(), d_rays, d_hits, d_inst, n, q, nullptr, to);
        std::vector<Hit> gh(n);
        std::vector<uint32_t> gi(n);
        ASSERT_EQ(cudaMemcpy(gh.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost), cudaSuccess);
        ASSERT_EQ(cudaMemcpy(gi.data(), d_inst, n * sizeof(uint32_t), cudaMemcpyDeviceToHost), cudaSuccess);
        size_t diff = 0;
        for (size_t i = 0; i < n; ++i) diff += std::memcmp(&gh[i], &ch[i], sizeof(Hit)) != 0 || gi[i] != ci[i];
        EXPECT_EQ(diff, 0u) << (q == Query::kAny ? "any" : "closest");
        EXPECT_EQ(gs.nodes_visited, cs.nodes_visited);
        EXPECT_EQ(gs.triangles_tested, cs.triangles_tested);
        EXPECT_EQ(gs.stack_overflows + gs.bad_indices + gs.invalid_rays, 0u);
    }
    cudaFree(d_rays);
    cudaFree(d_hits);
    cudaFree(d_inst);
}

TEST(TwoLevelGpu, SingleLevelSceneIsRefused) {
    if (!have_gpu()) GTEST_SKIP() << "no CUDA device";
    const TwoLevelBuild b = scene();
    Expected<DeviceScene> ds = DeviceScene::upload(b.nodes.data(), b.nodes.size(), b.tris.data(), b.tris.size(),
                                                   nullptr, 0);
    ASSERT_TRUE(ds.ok());
    EXPECT_FALSE(ds->has_two_level());
    EXPECT_THROW(trace_two_level(ds.value(), nullptr, nullptr, nullptr, 0, Query::kClosest), std::invalid_argument);
}

TEST(TwoLevelGpu, SingleLevelKernelsRefuseATwoLevelScene) {
    if (!have_gpu()) GTEST_SKIP() << "no CUDA device";
    const TwoLevelBuild b = scene();
    const TwoLevelSections t = top_level_sections(b);
    Expected<DeviceScene> ds =
        DeviceScene::upload(b.nodes.data(), b.nodes.size(), b.tris.data(), b.tris.size(), nullptr, 0, t);
    ASSERT_TRUE(ds.ok());
    EXPECT_THROW(trace(ds.value(), nullptr, nullptr, 0, Query::kClosest), std::invalid_argument);
}
#endif

TEST(TwoLevelGpu, UploadRefusesAnIncompleteTopLevel) {
    // Checked before any CUDA call, so it runs without a device too.
#if defined(CWBVH_HAVE_CUDA)
    const TwoLevelBuild b = scene();
    TwoLevelSections t;
    t.top_nodes = b.tlas.data();
    t.top_node_count = b.tlas.size();  // no INST, no MESH
    Expected<DeviceScene> ds =
        DeviceScene::upload(b.nodes.data(), b.nodes.size(), b.tris.data(), b.tris.size(), nullptr, 0, t);
    ASSERT_FALSE(ds.ok());
    EXPECT_NE(ds.error().message.find("TLAS, INST and MESH"), std::string::npos) << ds.error().message;
#else
    GTEST_SKIP() << "built without CUDA";
#endif
}

}  // namespace
}  // namespace cwbvh::test
