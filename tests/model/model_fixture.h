// The warp-model tests' scenes and checks, shared by warp_model_test.cpp (the CPU warp
// model) and kernel_emulation_test.cpp (the GPU kernels' bodies run on the CPU).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"

namespace cwbvh {
namespace model_test {

struct Fixture {
    SceneData scene;
    std::vector<Ray> rays;
};

/// A synthetic scene of `triangles` with width x width camera rays and their diffuse
/// bounce-1 rays, plus a ray that is not traceable (answered with a miss without
/// touching the tree) and one with a zero direction component.
inline Fixture make_fixture(int triangles, int width) {
    Fixture x;
    SyntheticOptions so;
    so.triangles = uint32_t(triangles);
    x.scene = make_synthetic_scene(so);
    const std::vector<Ray> primary = camera_rays(default_camera(x.scene.bounds), width, width);
    const DiffuseRays d = diffuse_rays(x.scene.nodes.data(), x.scene.nodes.size(), x.scene.triangles.data(),
                                       x.scene.triangles.size(), primary, 1, 7, 1);
    x.rays = primary;
    x.rays.insert(x.rays.end(), d.rays.begin(), d.rays.end());
    Ray bad = primary[0];
    bad.dir[0] = bad.dir[1] = bad.dir[2] = 0.0f;  // zero direction: not traceable
    x.rays.push_back(bad);
    Ray axis = primary[primary.size() / 2];
    axis.dir[0] = 0.0f;  // a zero component: the exact slab filter path
    x.rays.push_back(axis);
    return x;
}

inline std::vector<Hit> reference(const Fixture& f, HitMode mode, TriangleTest test) {
    std::vector<Hit> ref(f.rays.size());
    CpuTraceOptions o;
    o.mode = mode;
    o.test = test;
    o.threads = 1;
    trace_cwbvh_cpu(f.scene.nodes.data(), f.scene.nodes.size(), f.scene.triangles.data(), f.scene.triangles.size(),
                    f.rays.data(), ref.data(), f.rays.size(), o);
    return ref;
}

/// Closest hit: same t bit for bit and the same triangle, or another triangle at
/// exactly the same t (postponing may change which of two equal hits is last).
inline void expect_same_hits(const std::vector<Hit>& got, const std::vector<Hit>& ref, HitMode mode) {
    ASSERT_EQ(got.size(), ref.size());
    size_t bad = 0;
    for (size_t i = 0; i < ref.size(); ++i) {
        const bool gh = got[i].prim != kMissPrim, rh = ref[i].prim != kMissPrim;
        if (gh != rh || (mode == HitMode::kClosest && gh && got[i].t != ref[i].t)) {
            if (++bad <= 3) ADD_FAILURE() << "ray " << i << ": model prim " << got[i].prim << " t " << got[i].t
                                          << ", reference prim " << ref[i].prim << " t " << ref[i].t;
        }
        if (mode == HitMode::kClosest && gh && rh && got[i].prim == ref[i].prim) {
            EXPECT_EQ(got[i].u, ref[i].u) << "ray " << i << ": u is recomputed from the hit triangle, bit for bit";
            EXPECT_EQ(got[i].v, ref[i].v) << "ray " << i;
        }
    }
    EXPECT_EQ(bad, 0u);
}

}  // namespace model_test
}  // namespace cwbvh
