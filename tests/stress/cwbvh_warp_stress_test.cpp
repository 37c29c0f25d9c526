// The CWBVH kernel's lane code under its warp rules (the warp model, warp_model.h) on
// compiled meshes built to make the float stages of the watertight test give up: exact
// duplicate and coplanar overlapping triangles (hits at equal or nearly equal t, whose float
// bounds overlap), and rays through grid vertices and edge midpoints (edge functions of 0).
// There the deferred hits of cwbvh_lane.h (test_triangle_deferred) take their rare paths: a
// deferred hit finished inside a triangle round and the triangle tested again in the next,
// and the whole test against the exact distance. The answers must still be the CPU
// reference's (traverse.h): the same hit or miss, the same t bit for bit, and u, v bit for
// bit where the triangle is the same (closest hit; another triangle only at an equal t).
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <random>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/warp_model.h"
#include "stress/stress_support.h"

namespace cwbvh::stress {
namespace {

using test::Mesh;

/// A flat n x n grid, two exact duplicates of it, and three coplanar copies shifted by
/// fractions of a cell (overlapping triangles in one plane).
Mesh coplanar_stack(int n) {
    const Mesh g = test::grid_mesh(n, false);
    Mesh m;
    for (int c = 0; c < 4; ++c) {
        const uint32_t base = uint32_t(m.v.size() / 3);
        for (size_t i = 0; i < g.v.size(); i += 3) {
            m.v.push_back(g.v[i] + 0.25f * float(c));
            m.v.push_back(g.v[i + 1] + 0.125f * float(c));
            m.v.push_back(0.0f);
        }
        for (uint32_t x : g.idx) m.idx.push_back(base + x);
    }
    for (int c = 0; c < 2; ++c)
        for (uint32_t x : g.idx) m.idx.push_back(x);  // duplicates of copy 0
    return m;
}

struct Totals {
    uint64_t deferred = 0, finished_in_rounds = 0, finished_at_refill = 0, whole = 0, failures = 0;
};

void expect_model_matches_reference(const std::string& name, const File& f, const std::vector<Ray>& rays,
                                    HitMode mode, bool defer, Totals& t) {
    SCOPED_TRACE(name + (mode == HitMode::kAny ? " any" : " closest") + (defer ? " deferred" : " not deferred"));
    const auto nodes = f.nodes();
    const auto tris = f.triangles();
    std::vector<Hit> ref(rays.size()), got(rays.size());
    CpuTraceOptions o;
    o.mode = mode;
    o.threads = 2;
    trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), rays.data(), ref.data(), rays.size(), o);
    WarpModelOptions wo;
    wo.mode = mode;
    wo.warps = 8;
    wo.defer_hits = defer;
    const WarpModelStats s = model_cwbvh_warps(nodes.data(), nodes.size(), tris.data(), tris.size(), rays.data(),
                                               got.data(), rays.size(), wo);
    uint64_t bad = 0, ties = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        const bool gh = got[i].prim != kMissPrim, rh = ref[i].prim != kMissPrim;
        bool ok = gh == rh;
        if (ok && gh && mode == HitMode::kClosest) {
            ok = std::memcmp(&got[i].t, &ref[i].t, sizeof(float)) == 0;
            if (ok && got[i].prim == ref[i].prim)
                ok = std::memcmp(&got[i], &ref[i], sizeof(Hit)) == 0;
            else if (ok)
                ++ties;
        }
        if (!ok && ++bad <= 3)
            ADD_FAILURE() << "ray " << i << ": model prim " << got[i].prim << " t " << got[i].t << " u " << got[i].u
                          << ", reference prim " << ref[i].prim << " t " << ref[i].t << " u " << ref[i].u;
    }
    EXPECT_EQ(bad, 0u);
    EXPECT_EQ(s.stack_overflows + s.bad_indices, 0u);
    EXPECT_EQ(s.finalize_failures, 0u);
    std::printf("  %s %s%s: %zu rays, %llu differ, %llu ties; deferred %llu, finished in rounds %llu, at refills "
                "%llu, whole tests %llu\n",
                name.c_str(), mode == HitMode::kAny ? "any" : "closest", defer ? "" : " (not deferred)", rays.size(),
                (unsigned long long)bad, (unsigned long long)ties, (unsigned long long)s.lane_deferred_hits,
                (unsigned long long)s.lane_prev_finished, (unsigned long long)s.lane_finalized,
                (unsigned long long)s.lane_whole_tests);
    if (defer) {
        t.deferred += s.lane_deferred_hits;
        t.finished_in_rounds += s.lane_prev_finished;
        t.finished_at_refill += s.lane_finalized;
        t.whole += s.lane_whole_tests;
        t.failures += s.finalize_failures;
    }
}

class CwbvhWarpStress : public TempDirSuite {};

TEST_F(CwbvhWarpStress, DeferredHitsOnCoplanarStacksAndEdgeRays) {
    struct Case {
        const char* name;
        Mesh mesh;
        int grid;  ///< > 0: also rays through the vertices and edge midpoints of a grid of this size
    };
    std::vector<Case> cases;
    cases.push_back({"coplanar-stack+dups", coplanar_stack(16), 0});
    cases.push_back({"bumpy-grid", test::grid_mesh(24, true), 24});
    cases.push_back({"flat-grid", test::grid_mesh(24, false), 24});
    Totals t;
    for (const Case& c : cases) {
        File f;
        std::string err;
        ASSERT_TRUE(compile_and_open(write_obj(c.mesh, c.name), std::string(c.name) + "-warp", f, err)) << err;
        std::vector<Ray> rays = scene_rays(f, 4000, 48, 17);
        if (c.grid > 0) {
            const std::vector<Ray> edge = grid_point_rays(c.mesh, c.grid);
            rays.insert(rays.end(), edge.begin(), edge.end());
        }
        for (const HitMode mode : {HitMode::kClosest, HitMode::kAny})
            for (const bool defer : {true, false}) expect_model_matches_reference(c.name, f, rays, mode, defer, t);
    }
    // The rare paths ran: float could not decide (the whole test), and a deferred hit was
    // finished inside a round, not only at a refill.
    EXPECT_GT(t.deferred, 0u);
    EXPECT_GT(t.whole, 0u);
    EXPECT_GT(t.finished_in_rounds, 0u);
    EXPECT_GT(t.finished_at_refill, 0u);
    EXPECT_EQ(t.failures, 0u);
}

}  // namespace
}  // namespace cwbvh::stress
