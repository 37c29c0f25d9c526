// Secondary-ray building blocks as host/device code: counter-based random numbers, the
// self-intersection offset of a ray origin, and an orthonormal frame around a normal.
// One home for the ray generator (ray_gen.cpp: the diffuse benchmark rays) and for
// shading code that runs in a kernel (examples/inline_ao.h).
#pragma once

#include <cmath>
#include <cstdint>

#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/fp.h"

namespace cwbvh {

/// Counter-based random numbers: PCG hash (Jarzynski, Olano 2020, "Hash Functions
/// for GPU Rendering", JCGT 9(3)), so a value depends only on its coordinates.
CWBVH_HD inline uint32_t pcg_hash(uint32_t x) {
    const uint32_t state = x * 747796405u + 2891336453u;
    const uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

/// Uniform in [0, 1): 24 random bits of hash(seed, path, bounce, dim).
CWBVH_HD inline float random_unit(uint32_t seed, uint32_t path, uint32_t bounce, uint32_t dim) {
    const uint32_t h = pcg_hash(pcg_hash(pcg_hash(seed) ^ path) + bounce * 16u + dim);
    return float(h >> 8) * (1.0f / 16777216.0f);  // exact: 24 bits
}

/// Wächter, Binder 2019, "A Fast and Robust Method for Avoiding Self-Intersection"
/// (Ray Tracing Gems, ch. 6): move p off its surface along the unit normal n by a
/// fixed number of ulps per axis (a tiny absolute step near the origin). No scene
/// scale enters. Components that would leave the finite range stay unchanged.
CWBVH_HD inline void offset_ray_origin(const float p[3], const float n[3], float out[3]) {
    // Constants of the paper: origin() = 1/32, float_scale() = 1/65536, int_scale() = 256.
    constexpr float kOrigin = 1.0f / 32.0f, kFloatScale = 1.0f / 65536.0f, kIntScale = 256.0f;
    for (int a = 0; a < 3; ++a) {
        if (std::fabs(p[a]) < kOrigin) {
            out[a] = p[a] + kFloatScale * n[a];
            continue;
        }
        // |n| <= 1, so the ulp step is in [-256, 256]: no integer overflow.
        const int32_t of = int32_t(kIntScale * n[a]);
        const uint32_t bits = float_to_bits(p[a]);
        // Moving away from zero in ulps is + on the magnitude bits for either sign.
        const int32_t step = (p[a] < 0) ? -of : of;
        const int64_t mag = int64_t(bits & 0x7FFFFFFFu) + step;
        const float moved = bits_to_float((bits & 0x80000000u) | uint32_t(mag));  // |p| >= 1/32: mag stays > 0
        out[a] = is_finite_f(moved) ? moved : p[a];
    }
}

/// Two unit vectors t1, t2 that make (t1, t2, n) an orthonormal frame around the unit
/// normal n, without a branch on the frame (Duff et al. 2017, "Building an Orthonormal
/// Basis, Revisited", JCGT 6(1), listing 3).
CWBVH_HD inline void orthonormal_basis(const float n[3], float t1[3], float t2[3]) {
    const float sign = std::copysign(1.0f, n[2]);
    const float a = -1.0f / (sign + n[2]);
    const float b = n[0] * n[1] * a;
    t1[0] = 1.0f + sign * n[0] * n[0] * a;
    t1[1] = sign * b;
    t1[2] = -sign * n[0];
    t2[0] = b;
    t2[1] = sign + n[1] * n[1] * a;
    t2[2] = -n[1];
}

}  // namespace cwbvh
