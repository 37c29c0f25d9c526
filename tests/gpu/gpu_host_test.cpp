// Host-side tests of the GPU path: the stack spill/index logic and the warp policies
// (pure functions shared with the kernel), the no-GPU behaviour of every entry point,
// and - only when a CUDA device is present - GPU vs CPU traces of a synthetic scene.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <sys/wait.h>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/cwbvh_device.h"
#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/kernels/gpu_stack.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "cwbvh/kernels/trace.h"
#include "cwbvh/kernels/warp_model.h"

namespace cwbvh {
namespace {

TEST(GpuStack, SpillsPastSharedEntriesAndPopsInLifoOrder) {
    constexpr int kLanes = 32, kLane = 5;
    std::vector<PackedEntry> shared(size_t(kGpuSharedStackEntries) * kLanes, PackedEntry{0xDEADu, 0xDEADu});
    PackedEntry spill[kGpuLocalStackEntries];
    GpuStack s(shared.data() + kLane, spill);
    for (uint32_t i = 0; i < uint32_t(kGpuStackEntries); ++i) ASSERT_TRUE(s.push(StackEntry{i, 0x01000000u | i}));
    EXPECT_FALSE(s.push(StackEntry{99u, 99u})) << "a full stack reports overflow instead of writing";
    // Shared entries land in this lane's column only: [entry][lane].
    for (int e = 0; e < kGpuSharedStackEntries; ++e) {
        for (int l = 0; l < kLanes; ++l) {
            const PackedEntry& p = shared[size_t(e) * kLanes + l];
            if (l == kLane) {
                EXPECT_EQ(p.base, uint32_t(e));
            } else {
                EXPECT_EQ(p.base, 0xDEADu) << "entry " << e << " lane " << l;
            }
        }
    }
    for (int i = kGpuStackEntries - 1; i >= 0; --i) {
        ASSERT_FALSE(s.empty());
        const StackEntry e = s.pop();
        EXPECT_EQ(e.base, uint32_t(i));
        EXPECT_EQ(e.hits, 0x01000000u | uint32_t(i));
    }
    EXPECT_TRUE(s.empty());
}

TEST(GpuStack, SharedLayoutIsConflictFreeForAWarpAtOneDepth) {
    // 32 lanes' GpuStacks over one warp's shared block, as the kernel sets them up (lane l
    // at base + l, stride 32), each pushing to the same depth: the bytes each push wrote
    // must be two 128-byte wavefronts of 16 lanes without a repeated bank (4-byte banks,
    // 32 of them; an 8-byte entry takes two). Found by where each push landed, not by the
    // formula the layout is meant to follow.
    constexpr int kLanes = 32;
    std::vector<PackedEntry> shared(size_t(kGpuSharedStackEntries) * kLanes, PackedEntry{0u, 0u});
    std::vector<PackedEntry> spill(size_t(kGpuLocalStackEntries) * kLanes);
    std::vector<GpuStack> stacks;
    for (int lane = 0; lane < kLanes; ++lane)
        stacks.emplace_back(shared.data() + lane, spill.data() + size_t(lane) * kGpuLocalStackEntries);
    for (int depth = 0; depth < kGpuSharedStackEntries; ++depth) {
        std::vector<size_t> byte(kLanes, SIZE_MAX);
        for (int lane = 0; lane < kLanes; ++lane) {
            const uint32_t mark = 0x80000000u | uint32_t(depth << 8) | uint32_t(lane);
            ASSERT_TRUE(stacks[size_t(lane)].push(StackEntry{mark, 0u}));
            for (size_t k = 0; k < shared.size(); ++k)
                if (shared[k].base == mark) {
                    EXPECT_EQ(byte[size_t(lane)], SIZE_MAX) << "written twice";
                    byte[size_t(lane)] = k * sizeof(PackedEntry);
                }
            ASSERT_NE(byte[size_t(lane)], SIZE_MAX) << "depth " << depth << " lane " << lane << " not in shared";
        }
        for (int half = 0; half < 2; ++half) {
            uint32_t banks = 0;
            const size_t wavefront = byte[size_t(half * 16)] / 128;
            for (int lane = half * 16; lane < half * 16 + 16; ++lane) {
                const size_t b = byte[size_t(lane)];
                EXPECT_EQ(b / 128, wavefront) << "depth " << depth << " lane " << lane << ": outside its wavefront";
                const uint32_t b0 = uint32_t(b / 4) % 32, b1 = (b0 + 1) % 32;
                EXPECT_EQ(banks & ((1u << b0) | (1u << b1)), 0u) << "depth " << depth << " lane " << lane;
                banks |= (1u << b0) | (1u << b1);
            }
        }
    }
}

TEST(GpuPolicy, LostWorkCounter) {
    // The rule, whatever Nd and Nw are: lost += idle lanes - Nd, floored at 0.
    constexpr int kNd = kDynamicFetchNd, kNw = kDynamicFetchNw;
    static_assert(kNd >= 1 && kNd < 32 && kNw >= 1, "the paper's counter needs 0 < Nd < 32 and Nw > 0");
    EXPECT_EQ(update_lost_work(0, 32), 0);                  // full warp: no credit
    EXPECT_EQ(update_lost_work(0, 32 - kNd), 0);            // Nd idle lanes are free
    EXPECT_EQ(update_lost_work(0, 32 - kNd - 1), 1);        // one more is lost
    EXPECT_EQ(update_lost_work(5, 32 - kNd - 3), 8);        // accumulates
    EXPECT_EQ(update_lost_work(kNd - 1, 32), 0);            // a full step pays back up to Nd, floored
    EXPECT_EQ(update_lost_work(kNd + 2, 32), 2);
    EXPECT_EQ(update_lost_work(7, 20, 0), 19);              // the nd argument (warp model) replaces Nd
    // A warp with one idle lane beyond Nd per step refills (lost >= Nw) after exactly Nw steps.
    int lost = 0, steps = 0;
    while (lost < kNw) {
        lost = update_lost_work(lost, 32 - kNd - 1);
        ++steps;
        ASSERT_LE(steps, kNw);
    }
    EXPECT_EQ(steps, kNw);
    // The warp model starts from the kernel's constants.
    EXPECT_EQ(WarpModelOptions{}.fetch_nd, kNd);
    EXPECT_EQ(WarpModelOptions{}.fetch_nw, kNw);
}

TEST(GpuPolicy, PostponeBelowTwentyPercentOfActiveLanes) {
    EXPECT_TRUE(should_postpone(1, 32, true));
    EXPECT_TRUE(should_postpone(6, 32, true));    // 18.75%
    EXPECT_FALSE(should_postpone(7, 32, true));   // 21.9%
    EXPECT_TRUE(should_postpone(1, 32, false));   // kernel rule: with or without node work
    EXPECT_FALSE(should_postpone(1, 32, false, kPostponePercent, true));  // the old rule: test now
    EXPECT_FALSE(should_postpone(1, 5, true));    // 20% exactly is not "fewer than"
    EXPECT_TRUE(should_postpone(1, 6, true));
    EXPECT_FALSE(should_postpone(32, 32, false));  // everyone wants triangles: nobody waits
}

TEST(GpuNoDevice, EntryPointsFailCleanly) {
    std::string why;
    if (gpu_available(why)) GTEST_SKIP() << "a CUDA device is present";
    EXPECT_FALSE(why.empty());
    SceneData sd = make_synthetic_scene();
    auto ds = DeviceScene::upload(sd.nodes.data(), sd.nodes.size(), sd.triangles.data(), sd.triangles.size(),
                                  sd.bvh2.data(), sd.bvh2.size());
    EXPECT_FALSE(ds.ok());
    const std::string& error = ds.error().message;
    EXPECT_NE(error.find("cuda"), std::string::npos) << error;
    cwbvh_device_scene* out = reinterpret_cast<cwbvh_device_scene*>(0x1);
    char msg[256];
    EXPECT_EQ(cwbvh_device_upload(nullptr, &out, msg, sizeof msg), CWBVH_ERROR_INVALID_ARGUMENT);
    EXPECT_EQ(out, nullptr);
    cwbvh_device_free(nullptr);
}

TEST(GpuNoDevice, StatusTellsNoDeviceFromUnusableDevice) {
    // cwbvh_gpu_check skips only on kNoDevice / kNoCuda and fails on kUnusable, so the
    // two answers must agree with gpu_available and always carry a reason.
    std::string why, why2;
    const GpuStatus s = gpu_status(why);
    EXPECT_EQ(gpu_available(why2), s == GpuStatus::kReady);
    EXPECT_EQ(why, why2);
    EXPECT_EQ(why.empty(), s == GpuStatus::kReady) << why;
    if (s == GpuStatus::kNoDevice) {
        EXPECT_EQ(why.find("driver too old"), std::string::npos) << why;
    }
    if (s == GpuStatus::kUnusable) {
        EXPECT_EQ(why.find("no CUDA device"), std::string::npos) << why;
    }
}

TEST(GpuCheckTool, SkipsOrPassesOnSyntheticScene) {
    const std::string exe = std::string(CWBVH_BIN_DIR) + "/cwbvh_gpu_check";
    FILE* f = std::fopen(exe.c_str(), "rb");
    if (!f) GTEST_SKIP() << exe << " not built";
    std::fclose(f);
    const std::string out = std::string(CWBVH_BINARY_DIR) + "/gpu_check_test_output.txt";
    const int rc = std::system((exe + " --width 128 --height 96 --repeat 1 > " + out + " 2>&1").c_str());
    // Exit 0: PASS, or SKIPPED without a device. A device that is present but cannot run
    // the kernels makes the tool exit 2, and this test fail.
    EXPECT_EQ(rc, 0);
    std::string why;
    if (gpu_status(why) != GpuStatus::kReady) {
        FILE* o = std::fopen(out.c_str(), "rb");
        ASSERT_NE(o, nullptr);
        char buf[256] = {};
        const size_t n = std::fread(buf, 1, sizeof buf - 1, o);
        std::fclose(o);
        EXPECT_EQ(std::string(buf, n).rfind("SKIPPED: no CUDA device", 0), 0u) << buf;
    }
}

// --deadline-s (scripts/gpu-check.sh: DEADLINE_S): past it the check starts no scene or view,
// prints where it stopped and its tables, and exits 4 (RESULT: PARTIAL on a GPU). CPU only: 40
// copies of the bunny at 1024 x 1024 (each view's CPU reference: five bounces, closest and any
// hit) outlast 1 s on any machine, so the deadline stops the run after a few of them.
TEST(GpuCheckTool, DeadlineStopsBeforeTheNextViewAndSaysSo) {
    const std::string bin = std::string(CWBVH_BIN_DIR);
    const std::string bunny = "/usr/share/glmark2/models/bunny.obj";
    FILE* f = std::fopen((bin + "/cwbvh_gpu_check").c_str(), "rb");
    if (!f) GTEST_SKIP() << "cwbvh_gpu_check not built";
    std::fclose(f);
    if (!(f = std::fopen(bunny.c_str(), "rb"))) GTEST_SKIP() << bunny << " absent (glmark2-data)";
    std::fclose(f);
    // The scene key is the file's stem: bunny, whose catalog views start with front.
    const std::string dir = std::string(CWBVH_BINARY_DIR) + "/gpu_check_deadline";
    ASSERT_EQ(std::system(("mkdir -p " + dir).c_str()), 0);
    const std::string file = dir + "/bunny.cwbvh", out = dir + "/output.txt";
    ASSERT_EQ(std::system((bin + "/cwbvhc " + bunny + " -o " + file + " --quiet").c_str()), 0);
    std::string files;
    for (int i = 0; i < 40; ++i) files += " " + file;
    const std::string cmd = bin + "/cwbvh_gpu_check --cpu-only --width 1024 --height 1024 --repeat 1 --deadline-s 1" +
                            files + " > " + out + " 2>&1";
    const int rc = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(rc));
    EXPECT_EQ(WEXITSTATUS(rc), 4);
    std::string text;
    if (FILE* o = std::fopen(out.c_str(), "rb")) {
        char buf[4096];
        size_t n;
        while ((n = std::fread(buf, 1, sizeof buf, o)) > 0) text.append(buf, n);
        std::fclose(o);
    }
    EXPECT_NE(text.find("DEADLINE: stopped before scene bunny"), std::string::npos) << text;
    EXPECT_NE(text.find("bunny view front"), std::string::npos) << "the first view ran";
    EXPECT_NE(text.find("(partial: deadline)"), std::string::npos) << text;
    std::remove(file.c_str());
}

TEST(GpuTrace, MatchesCpuOnSyntheticScene) {
    std::string why;
    if (!gpu_available(why)) GTEST_SKIP() << "SKIPPED: no CUDA device (" << why << ")";
    SyntheticOptions so;
    so.triangles = 3000;
    SceneData sd = make_synthetic_scene(so);
    auto ds = DeviceScene::upload(sd.nodes.data(), sd.nodes.size(), sd.triangles.data(), sd.triangles.size(),
                                  sd.bvh2.data(), sd.bvh2.size());
    ASSERT_TRUE(ds.ok()) << ds.error().message;
    // Rays from above the grid, straight down and oblique, plus invalid ones.
    std::vector<Ray> rays;
    for (int i = 0; i < 20000; ++i) {
        const float x = sd.bounds.lo[0] + (sd.bounds.hi[0] - sd.bounds.lo[0]) * float(i % 200) / 199.0f;
        const float y = sd.bounds.lo[1] + (sd.bounds.hi[1] - sd.bounds.lo[1]) * float(i / 200) / 99.0f;
        Ray r{{x, y, sd.bounds.hi[2] + 1.0f}, 0.0f, {0.01f * float(i % 7), -0.02f * float(i % 5), -1.0f}, kInfinity};
        if (i % 997 == 0) r.dir[0] = r.dir[1] = r.dir[2] = 0.0f;  // invalid: miss
        rays.push_back(r);
    }
    const size_t n = rays.size();
    Ray* d_rays = nullptr;
    Hit* d_hits = nullptr;
    ASSERT_EQ(cudaMalloc(reinterpret_cast<void**>(&d_rays), n * sizeof(Ray)), cudaSuccess);
    ASSERT_EQ(cudaMalloc(reinterpret_cast<void**>(&d_hits), n * sizeof(Hit)), cudaSuccess);
    ASSERT_EQ(cudaMemcpy(d_rays, rays.data(), n * sizeof(Ray), cudaMemcpyHostToDevice), cudaSuccess);
    for (int any = 0; any < 2; ++any) {
        std::vector<Hit> ref(n);
        CpuTraceOptions co;
        co.mode = any ? HitMode::kAny : HitMode::kClosest;
        trace_cwbvh_cpu(sd.nodes.data(), sd.nodes.size(), sd.triangles.data(), sd.triangles.size(), rays.data(),
                        ref.data(), n, co);
        // 0 BVH2; 1 CWBVH; 2, 3 its A/B variants (no deferred hits; the reference node test).
        for (int variant = 0; variant < 4; ++variant) {
            const bool bvh2 = variant == 0;
            DeviceTraceStats st;
            TraceOptions to;
            to.stats = &st;
            to.defer_hits = variant != 2;
            to.fast_node_test = variant != 3;
            const Query q = any ? Query::kAny : Query::kClosest;
            if (bvh2) trace_bvh2(*ds, d_rays, d_hits, n, q, nullptr, to);
            else trace(*ds, d_rays, d_hits, n, q, nullptr, to);
            std::vector<Hit> got(n);
            ASSERT_EQ(cudaMemcpy(got.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost), cudaSuccess);
            EXPECT_EQ(st.stack_overflows, 0u);
            EXPECT_EQ(st.bad_indices, 0u);
            size_t bad = 0;
            for (size_t i = 0; i < n; ++i) {
                const bool gh = got[i].prim != kMissPrim, ch = ref[i].prim != kMissPrim;
                if (gh != ch || (!any && gh && got[i].t != ref[i].t)) ++bad;
            }
            EXPECT_EQ(bad, 0u) << (bvh2 ? "bvh2" : "cwbvh") << " variant " << variant << (any ? " any" : " closest");
        }
    }
    cudaFree(d_rays);
    cudaFree(d_hits);
}

}  // namespace
}  // namespace cwbvh
