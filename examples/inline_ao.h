// inline_ao: ambient occlusion written the way a renderer writes its own shading code,
// with the inline queries of cwbvh/kernels/query.h. ao_pixel() is host/device code: the
// same function runs in the CUDA kernel (inline_ao_gpu.cu) and in the CPU loop
// (inline_ao.cpp), over a SceneView of device or host pointers.
#pragma once

#include <cmath>
#include <cstdint>

#include "cwbvh/kernels/query.h"

namespace cwbvh::example {

struct AoParams {
    int samples;    ///< occlusion rays per pixel
    float radius;   ///< occlusion distance (world units)
    float epsilon;  ///< occlusion rays start this far along the normal (world units), plus 1e-6 of the hit's largest coordinate
};

/// A small hash (Jarvis' PCG step): per-pixel, per-sample random numbers in [0, 1).
CWBVH_HD inline float hash01(uint32_t& state) {
    state = state * 747796405u + 2891336453u;
    uint32_t w = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    w = (w >> 22u) ^ w;
    return float(w >> 8) * (1.0f / 16777216.0f);
}

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
    // An orthonormal frame around n (Duff et al. 2017).
    const float sign = n[2] >= 0.0f ? 1.0f : -1.0f;
    const float ka = -1.0f / (sign + n[2]), kb = n[0] * n[1] * ka;
    const float t1[3] = {1.0f + sign * n[0] * n[0] * ka, sign * kb, -sign * n[0]};
    const float t2[3] = {kb, sign + n[1] * n[1] * ka, -n[1]};

    // The occlusion rays start off the surface: by the scene-relative epsilon, and by a few
    // float spacings of the hit point's coordinates (its rounding, far from the origin).
    float hit[3], mag = 0.0f;
    for (int a = 0; a < 3; ++a) {
        hit[a] = ray.org[a] + q.hit.t * ray.dir[a];
        mag = std::fmax(mag, std::fabs(hit[a]));
    }
    const float eps = c.epsilon + 1e-6f * mag;
    for (int a = 0; a < 3; ++a) hit[a] += eps * n[a];
    uint32_t rng = pixel * 9781u + 1u;
    int open = 0;
    for (int s = 0; s < c.samples; ++s) {
        const float u1 = hash01(rng), u2 = hash01(rng);
        const float r = std::sqrt(u1), phi = 6.2831853f * u2;
        const float lx = r * std::cos(phi), ly = r * std::sin(phi), lz = std::sqrt(1.0f - u1 > 0.0f ? 1.0f - u1 : 0.0f);
        Ray occ;
        for (int a = 0; a < 3; ++a) {
            occ.org[a] = hit[a];
            occ.dir[a] = lx * t1[a] + ly * t2[a] + lz * n[a];
        }
        occ.tmin = 0.0f;
        occ.tmax = c.radius;
        open += occluded(scene, occ) ? 0 : 1;  // any hit
    }
    return float(open) / float(c.samples);
}

}  // namespace cwbvh::example
