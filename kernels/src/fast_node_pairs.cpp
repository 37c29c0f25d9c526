// fast_node_pairs.h
#include "cwbvh/kernels/fast_node_pairs.h"

#include <cmath>
#include <random>

namespace cwbvh {

FastNodePairs make_fast_node_pairs(const CwbvhNode* nodes, size_t count, uint64_t seed, size_t pairs) {
    FastNodePairs out;
    out.scale = count ? node_scale(nodes, count) : NodeScale{};
    std::mt19937_64 g(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (size_t tries = 0; out.scale.usable && out.nodes.size() < pairs && tries < 8 * pairs; ++tries) {
        const CwbvhNode& n = nodes[g() % count];
        const int slot = int(g() % 8);
        if (n.meta[slot] == 0) continue;
        Ray ray;
        float size = 0.0f, len = 0.0f;
        for (int a = 0; a < 3; ++a) size = std::fmax(size, std::ldexp(255.0f, int(n.e[a]) - 127));
        const float dist = size * (g() % 4 == 0 ? 100.0f : 2.0f) * u(g);
        for (int a = 0; a < 3; ++a) {
            ray.dir[a] = 2.0f * u(g) - 1.0f;
            if (g() % 16 == 0) ray.dir[a] *= 1e-4f;  // nearly axis-parallel
            len += ray.dir[a] * ray.dir[a];
        }
        len = std::sqrt(len);
        for (int a = 0; a < 3; ++a) {
            const float q = float(n.q_lo[a][slot]) + u(g) * float(n.q_hi[a][slot] - n.q_lo[a][slot]);
            const float target = n.p[a] + std::ldexp(q, int(n.e[a]) - 127);
            ray.org[a] = target - dist * ray.dir[a] / len;
        }
        ray.tmin = g() % 4 == 0 ? u(g) * size : 0.0f;
        ray.tmax = g() % 2 == 0 ? kInfinity : u(g) * 200.0f * size;
        if (!ray_is_traceable(ray)) continue;
        NodeRay nr = make_node_ray(ray);
        enable_fast_node_test(nr, out.scale, ray.dir, ray.tmin);
        if (!nr.uses_fast_test()) continue;
        out.nodes.push_back(n);
        out.rays.push_back(ray);
        out.node_rays.push_back(nr);
    }
    return out;
}

}  // namespace cwbvh
