// Shared by the kernels area's tests (two_level_gpu_test.cpp, query_test.cpp): the
// instanced test scene, its device upload, and whether a usable GPU is present.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "../traverse/two_level_scene.h"
#include "cwbvh/kernels/gpu_trace.h"
#if defined(CWBVH_HAVE_CUDA)
#include "cwbvh/kernels/device_scene.h"
#endif

namespace cwbvh::test {

/// Two meshes (a sphere of 6x6 quads per cube face and an 8x8 bumpy grid) placed
/// `placements` times in [0, 40]^3 with random rotations about z, scales in [0.5, 2]
/// and every 4th placement mirrored.
inline TwoLevelBuild instanced_test_scene(uint32_t seed, uint32_t placements) {
    Mesh sphere = cube_mesh(6, true);
    sphere.transform(1.0, -3.0);
    Mesh grid = grid_mesh(8);
    grid.transform(0.5, -2.0);
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> pos(0, 40), sc(0.5, 2), ang(0, 6.283185307179586);
    std::vector<Placement> p;
    for (uint32_t i = 0; i < placements; ++i) {
        const double a = ang(rng), s = sc(rng) * ((i % 4 == 3) ? -1 : 1), c = std::cos(a), n = std::sin(a);
        const double m[3][4] = {{c * s, -n, 0, pos(rng)}, {n * s, c, 0, pos(rng)}, {0, 0, sc(rng), pos(rng)}};
        p.push_back(make_placement(i % 2, m));
    }
    return build_two_level({sphere.tris(), grid.tris()}, p);
}

#if defined(CWBVH_HAVE_CUDA)
/// The top-level sections of `b` (TLAS, INST, MESH) for DeviceScene::upload.
inline TwoLevelSections top_level_sections(const TwoLevelBuild& b) {
    TwoLevelSections t;
    t.top_nodes = b.tlas.data();
    t.top_node_count = b.tlas.size();
    t.instances = b.instances.data();
    t.instance_count = b.instances.size();
    t.meshes = b.meshes.data();
    t.mesh_count = b.meshes.size();
    return t;
}
#endif

/// True when a CUDA device can run the kernels; false (the caller skips) when there is
/// no device or no CUDA; a device that is present but cannot run them fails the test.
inline bool have_gpu() {
    std::string why;
    const GpuStatus s = gpu_status(why);
    if (s == GpuStatus::kNoDevice || s == GpuStatus::kNoCuda) return false;
    EXPECT_EQ(s, GpuStatus::kReady) << why;
    return s == GpuStatus::kReady;
}

}  // namespace cwbvh::test
