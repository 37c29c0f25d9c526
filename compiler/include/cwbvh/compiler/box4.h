// Box4: an Aabb held in two 4-lane float vectors for the builder's binning
// loops (GCC/Clang vector extensions: SSE on x86-64, NEON on arm64, scalar
// code elsewhere). Lanes 0..2 are x, y, z; lane 3 carries a copy of another
// coordinate and is never read.
//
// Exactness: merge() computes (b < a) ? b : a for the lower and
// (a < b) ? b : a for the upper corner, lane by lane: std::min(a, b) and
// std::max(a, b), bit for bit (signed zeros included), so a Box4 union equals
// the scalar merge() of the same boxes in any order the scalar code used.
// grow() is Aabb::grow(point), bit for bit. half_area() is
// Aabb::half_area() on the same three coordinates.
#pragma once

#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

using F4 = float __attribute__((vector_size(16)));
using I4 = int __attribute__((vector_size(16)));

struct Box4 {
    F4 lo = {Aabb::kInf, Aabb::kInf, Aabb::kInf, Aabb::kInf};
    F4 hi = {-Aabb::kInf, -Aabb::kInf, -Aabb::kInf, -Aabb::kInf};

    /// Two unaligned 16-byte loads from the Aabb's 24 bytes (lo[0..2] hi[0],
    /// then lo[2] hi[0..2], moved down one lane).
    static Box4 of(const Aabb& b) {
        static_assert(sizeof(Aabb) == 24, "Aabb: six packed floats");
        Box4 r;
        std::memcpy(&r.lo, &b.lo[0], 16);
        F4 h;
        std::memcpy(&h, &b.lo[2], 16);
#if defined(__clang__)  // the fuzz build (clang); GCC builds keep __builtin_shuffle
        r.hi = __builtin_shufflevector(h, h, 1, 2, 3, 3);
#else
        r.hi = __builtin_shuffle(h, I4{1, 2, 3, 3});
#endif
        return r;
    }
    void merge(const Box4& b) {
#if defined(__SSE2__)
        // minps(x, y) = x < y ? x : y, maxps(x, y) = x > y ? x : y.
        lo = F4(_mm_min_ps(__m128(b.lo), __m128(lo)));
        hi = F4(_mm_max_ps(__m128(b.hi), __m128(hi)));
#else
        lo = b.lo < lo ? b.lo : lo;
        hi = hi < b.hi ? b.hi : hi;
#endif
    }
    /// Aabb::grow(point) lane by lane: (lo < p) ? lo : p and (hi > p) ? hi : p
    /// (ties take p, unlike merge()).
    void grow(const F4& p) {
        lo = lo < p ? lo : p;
        hi = hi > p ? hi : p;
    }
    Aabb aabb() const {
        Aabb r;
        for (int a = 0; a < 3; ++a) {
            r.lo[a] = lo[a];
            r.hi[a] = hi[a];
        }
        return r;
    }
    bool empty() const {
#if defined(__SSE2__)
        return (_mm_movemask_ps(_mm_cmple_ps(__m128(lo), __m128(hi))) & 7) != 7;
#else
        return !(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2]);
#endif
    }
    /// (dx * dy + dy * dz) + dz * dx with d = double(hi) - double(lo), as
    /// Aabb::half_area (each step one IEEE double operation, same order).
    double half_area() const {
        if (empty()) return 0.0;
#if defined(__SSE2__)
        const __m128d d01 = _mm_sub_pd(_mm_cvtps_pd(__m128(hi)), _mm_cvtps_pd(__m128(lo)));  // dx, dy
        const __m128 hi23 = _mm_movehl_ps(__m128(hi), __m128(hi)), lo23 = _mm_movehl_ps(__m128(lo), __m128(lo));
        const __m128d d23 = _mm_sub_pd(_mm_cvtps_pd(hi23), _mm_cvtps_pd(lo23));         // dz, (lane 3)
        const __m128d p = _mm_mul_pd(d01, _mm_shuffle_pd(d01, d23, 1));                  // dx*dy, dy*dz
        const double dzdx = _mm_cvtsd_f64(_mm_mul_sd(d23, d01));                         // dz*dx
        return (_mm_cvtsd_f64(p) + _mm_cvtsd_f64(_mm_unpackhi_pd(p, p))) + dzdx;
#else
        const double dx = double(hi[0]) - lo[0], dy = double(hi[1]) - lo[1], dz = double(hi[2]) - lo[2];
        return dx * dy + dy * dz + dz * dx;
#endif
    }
};

}  // namespace cwbvh::compiler
