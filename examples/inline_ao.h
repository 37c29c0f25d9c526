// inline_ao: ambient occlusion written the way a renderer writes its own shading code,
// with the inline queries of cwbvh/kernels/query.h. ao_pixel() is host/device code: the
// same function runs in the CUDA kernel (inline_ao_gpu.cu) and in the CPU loop
// (inline_ao.cpp), over a SceneView of device or host pointers.
#pragma once

#include <cmath>
#include <cstdint>

#include "cwbvh/kernels/query.h"
#include "cwbvh/kernels/ray_sampling.h"

namespace cwbvh::example {

struct AoParams {
    int samples;   ///< occlusion rays per pixel
    float radius;  ///< occlusion distance (world units)
};

CWBVH_HD inline void cross3(const float* a, const float* b, float* c) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/// The hit triangle's vertices in world space: the record's, moved by its instance's
/// object_to_world in a two-level scene.
CWBVH_HD inline void world_vertices(const SceneView& scene, const QueryHit& q, float (&v)[3][3]) {
    const TriangleRecord& t = scene.sections.tris[q.record];
    const float* src[3] = {t.v0, t.v1, t.v2};
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) v[k][a] = src[k][a];
    if (q.instance == kInvalidIndex) return;
    const float(&m)[3][4] = scene.sections.instances[q.instance].object_to_world;
    for (int k = 0; k < 3; ++k) {
        const float p[3] = {v[k][0], v[k][1], v[k][2]};
        for (int a = 0; a < 3; ++a) v[k][a] = m[a][0] * p[0] + m[a][1] * p[1] + m[a][2] * p[2] + m[a][3];
    }
}

/// Pixel `pixel` seen along `ray`: -1 where the ray misses, else the unoccluded share of
/// `samples` cosine-distributed rays of length `radius` from the hit point (1 = open,
/// 0 = enclosed).
CWBVH_HD inline float ao_pixel(const SceneView& scene, const AoParams& c, const Ray& ray, uint32_t pixel) {
    const QueryHit q = intersect(scene, ray);  // closest hit
    if (q.hit.prim == kMissPrim) return -1.0f;

    // Geometric normal, facing the camera.
    float v[3][3];
    world_vertices(scene, q, v);
    const float e1[3] = {v[1][0] - v[0][0], v[1][1] - v[0][1], v[1][2] - v[0][2]};
    const float e2[3] = {v[2][0] - v[0][0], v[2][1] - v[0][1], v[2][2] - v[0][2]};
    float n[3];
    cross3(e1, e2, n);
    const float len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0f)) return 0.0f;
    const float side = (n[0] * ray.dir[0] + n[1] * ray.dir[1] + n[2] * ray.dir[2]) > 0.0f ? -1.0f : 1.0f;
    for (float& a : n) a *= side / len;
    // The frame around n and the occlusion rays' origin: the hit point from the
    // barycentrics (closer to the surface than org + t dir), moved off it by
    // offset_ray_origin (a few ulps per axis: no scene scale, no epsilon), as the
    // library's diffuse rays are (ray_gen.cpp, diffuse_ray).
    float t1[3], t2[3], p[3], org[3];
    orthonormal_basis(n, t1, t2);
    for (int a = 0; a < 3; ++a)
        p[a] = v[0][a] + q.hit.u * (v[1][a] - v[0][a]) + q.hit.v * (v[2][a] - v[0][a]);
    offset_ray_origin(p, n, org);
    int open = 0;
    for (int s = 0; s < c.samples; ++s) {
        // Cosine-weighted (Malley): uniform on the disk, projected up.
        const float u1 = random_unit(1u, pixel, 0u, 2u * uint32_t(s)), u2 = random_unit(1u, pixel, 0u, 2u * uint32_t(s) + 1u);
        const float r = std::sqrt(u1), phi = 6.2831853f * u2;
        const float lx = r * std::cos(phi), ly = r * std::sin(phi), lz = std::sqrt(1.0f - u1);
        Ray occ;
        for (int a = 0; a < 3; ++a) {
            occ.org[a] = org[a];
            occ.dir[a] = lx * t1[a] + ly * t2[a] + lz * n[a];
        }
        occ.tmin = 0.0f;
        occ.tmax = c.radius;
        open += occluded(scene, occ) ? 0 : 1;  // any hit
    }
    return float(open) / float(c.samples);
}

}  // namespace cwbvh::example
