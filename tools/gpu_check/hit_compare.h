// The one comparison of GPU hits with the CPU reference: cwbvh_gpu_check uses it for
// the CWBVH and BVH2 kernels and the OptiX peer, cwbvh_optix_trace (bench/optix) for a
// hit file against a reference hit file. Header-only, host code.
//
// Closest hit: a hit matches the reference when both miss, or both hit the same prim
// with |t - t_ref| <= ulp_bound float ulps. A different prim with t within the bound
// is a "tie" (two triangles at the same distance: which one wins depends on test
// order) and accepted. Anything else (hit vs miss, t out of bound) is a mismatch.
// Any hit: only hit/miss must agree.
//
// Bounds: kKernelUlpBound = 4 for our kernels: the watertight float path uses only
// correctly rounded operations (fp.h), so it is bit-identical on host and device; the
// double fallback may be contracted into FMAs by nvcc, which moves the double result by
// an ulp of double, and at most 1 float ulp after rounding; 4 leaves margin.
// kOptixUlpBound = 64 (2^-17 relative, 0.8e-5) for OptiX, whose triangle test is its
// own (not watertight in our sense, t computed its way): its mismatches are counted
// and printed, never a failure of the check; hit-vs-miss disagreements at shared edges
// and silhouettes are expected there.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "cwbvh/kernels/ray.h"

namespace cwbvh {

inline constexpr uint32_t kKernelUlpBound = 4;
inline constexpr uint32_t kOptixUlpBound = 64;

/// Distance in float ulps (0xFFFFFFFF when either is inf or NaN and they differ).
inline uint32_t ulp_distance(float a, float b) {
    if (a == b) return 0;
    if (std::isinf(a) || std::isinf(b) || std::isnan(a) || std::isnan(b)) return 0xFFFFFFFFu;
    int32_t ia, ib;
    std::memcpy(&ia, &a, 4);
    std::memcpy(&ib, &b, 4);
    if (ia < 0) ia = int32_t(0x80000000u - uint32_t(ia));
    if (ib < 0) ib = int32_t(0x80000000u - uint32_t(ib));
    const int64_t d = int64_t(ia) - int64_t(ib);
    return uint32_t(std::min<int64_t>(d < 0 ? -d : d, 0xFFFFFFFF));
}

struct HitCompare {
    uint64_t mismatches = 0;  ///< hit vs miss, or t beyond the bound (closest hit)
    uint64_t hit_vs_miss = 0; ///< of the mismatches: one hits, the other misses
    uint64_t ties = 0;        ///< different prim at t within the bound: accepted
    int64_t first_bad = -1;   ///< index of the first mismatch, -1 if none
};

/// Compares hits[i] with ref[i] for i < ref.size() (hits.size() >= ref.size()).
inline HitCompare compare_hits(const std::vector<Hit>& hits, const std::vector<Hit>& ref, bool any,
                               uint32_t ulp_bound) {
    HitCompare c;
    for (size_t i = 0; i < ref.size(); ++i) {
        const bool gh = hits[i].prim != kMissPrim, ch = ref[i].prim != kMissPrim;
        bool bad = gh != ch;
        if (bad) ++c.hit_vs_miss;
        if (!bad && gh && !any) {
            if (ulp_distance(hits[i].t, ref[i].t) > ulp_bound) bad = true;
            else if (hits[i].prim != ref[i].prim) ++c.ties;
        }
        if (bad) {
            if (c.first_bad < 0) c.first_bad = int64_t(i);
            ++c.mismatches;
        }
    }
    return c;
}

}  // namespace cwbvh
