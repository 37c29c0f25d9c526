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
//
// compare_with_flattened: a two-level (instanced) file's hits against the flattened
// file's on the same world rays (issue 19: hit/miss equal; t within 1e-5 relative; the
// same PMAP source or an equal-t tie). The categories are those of
// tests/traverse/two_level_files_test.cpp's CPU check: a hit-vs-miss whose hitting
// side lies within 1e-5 (barycentric) of an edge is counted apart ("edge": the two
// files round differently there: world vertices vs the object-space ray), and so is a
// pair of hits on different source triangles at a t not close whose nearer hit lies at
// an edge (the same case with something behind the edge); a t beyond
// 1e-5 relative whose gap along the flattened triangle's normal is within the rounding
// of world coordinates (`slack`: diffuse rays leave from a surface) is counted apart
// ("rounding"). Every other difference is a disagreement.
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

inline constexpr double kFlatRelT = 1e-5;    ///< issue 19: t within 1e-5 relative
inline constexpr double kFlatEdgeBary = 1e-5; ///< a hit this close to an edge may go either way
/// Rounding of world coordinates of size `extent` (float): 16 u, u = 2^-24, times the
/// extent (tests/traverse/two_level_files_test.cpp's bound).
inline double flat_rounding_slack(double extent) { return 16.0 * 5.9604644775390625e-08 * extent; }

struct FlatCompare {
    uint64_t rays = 0, hits = 0;  ///< compared rays; of them, both hit
    uint64_t hit_vs_miss = 0;     ///< one hits, the other misses, not at an edge: disagreement
    uint64_t edge = 0;            ///< one hits, the other misses (or hits another triangle farther away),
                                  ///< the nearer hit within kFlatEdgeBary of an edge
    uint64_t t_far = 0;           ///< t beyond 1e-5 relative and beyond the rounding: disagreement
    uint64_t t_rounding = 0;      ///< t beyond 1e-5 relative, within the rounding along the normal
    uint64_t source = 0;          ///< different PMAP source, t not close: disagreement
    uint64_t ties = 0;            ///< different PMAP source at a close t: accepted
    uint64_t disagreeing = 0;     ///< rays with any disagreement
    double worst_rel = 0;         ///< largest relative t gap among the hits within 1e-5
    int64_t first_bad = -1;       ///< first disagreeing ray, -1 if none
    FlatCompare& operator+=(const FlatCompare& o) {
        if (first_bad < 0 && o.first_bad >= 0) first_bad = int64_t(rays) + o.first_bad;
        rays += o.rays;
        hits += o.hits;
        hit_vs_miss += o.hit_vs_miss;
        edge += o.edge;
        t_far += o.t_far;
        t_rounding += o.t_rounding;
        source += o.source;
        ties += o.ties;
        disagreeing += o.disagreeing;
        worst_rel = std::max(worst_rel, o.worst_rel);
        return *this;
    }
};

/// two[i] (the two-level file's hit) against flat[i] (the flattened file's) for
/// i < flat.size(). Any hit: hit/miss only. Closest hit: same_source(two_prim,
/// flat_prim) says whether both stored triangles come from the same source triangle
/// (PMAP: input, mesh, primitive, triangle); normal_cos(i, flat_prim) is |n . d| of
/// ray i's direction with the flattened triangle's unit normal (< 0: unknown, then
/// only 1e-5 relative counts as close); slack: flat_rounding_slack(scene extent).
template <class SameSource, class NormalCos>
FlatCompare compare_with_flattened(const std::vector<Hit>& two, const std::vector<Hit>& flat, bool any, double slack,
                                   SameSource&& same_source, NormalCos&& normal_cos) {
    FlatCompare c;
    for (size_t i = 0; i < flat.size(); ++i) {
        ++c.rays;
        const bool ha = two[i].prim != kMissPrim, hb = flat[i].prim != kMissPrim;
        bool bad = false;
        auto at_edge = [](const Hit& h) {
            return std::min({double(h.u), double(h.v), 1.0 - double(h.u) - double(h.v)}) <= kFlatEdgeBary;
        };
        if (ha != hb) {
            if (at_edge(ha ? two[i] : flat[i])) {
                ++c.edge;
            } else {
                ++c.hit_vs_miss;
                bad = true;
            }
        } else if (ha) {
            ++c.hits;
            if (!any) {
                const double gap = std::fabs(double(two[i].t) - double(flat[i].t));
                const double rel = gap / std::fabs(double(flat[i].t));
                bool close = rel <= kFlatRelT;
                if (close) {
                    c.worst_rel = std::max(c.worst_rel, rel);
                } else {
                    const double cs = normal_cos(i, flat[i].prim);
                    close = cs >= 0 && gap * cs <= slack;
                    if (close) {
                        ++c.t_rounding;
                    } else if (at_edge(two[i].t < flat[i].t ? two[i] : flat[i]) &&
                               !same_source(two[i].prim, flat[i].prim)) {
                        // The nearer hit lies on an edge of a triangle that the other
                        // file's rounding missed there (a silhouette): the hit/miss edge
                        // case with something behind it.
                        ++c.edge;
                        continue;
                    } else {
                        ++c.t_far;
                        bad = true;
                    }
                }
                if (!same_source(two[i].prim, flat[i].prim)) {
                    if (close) {
                        ++c.ties;
                    } else {
                        ++c.source;
                        bad = true;
                    }
                }
            }
        }
        if (bad) {
            ++c.disagreeing;
            if (c.first_bad < 0) c.first_bad = int64_t(i);
        }
    }
    return c;
}

/// The inline query and the two-level kernel against their CPU references
/// (trace_cwbvh_cpu, trace_two_level_cpu) on the same rays. `inst`/`ref_inst`: instances
/// (kInvalidIndex throughout for a single-level scene).
///  - Closest hit: the same Hit record and instance bit for bit; else, both hitting,
///    another (prim, instance) at t within kKernelUlpBound is a tie (counted, accepted:
///    the fast node test is conservative, so a kernel may test extra leaves and the
///    closed interval keeps whichever of two triangles at one distance came last), and
///    the same (prim, instance) at t within the bound is "near" (accepted, the double
///    path's FMA contraction, as compare_hits); anything else is a mismatch.
///  - Any hit: which hit a query reports depends on its traversal order, so the
///    reference's any-hit record is not the answer: hit/miss must agree with `ref`, and
///    a hit may not lie nearer than the closest hit `closest` (by more than the bound):
///    such a hit would be no hit at all.
struct QueryCompare {
    uint64_t mismatches = 0;   ///< a failure
    uint64_t not_bitwise = 0;  ///< rays whose record or instance differs from the reference's in any bit
    uint64_t ties = 0;         ///< closest hit: another triangle at the same t (accepted)
    uint64_t near = 0;         ///< closest hit: the same triangle, t within kKernelUlpBound (accepted)
    int64_t first_bad = -1;    ///< first mismatching ray, -1 if none (not summed: rays of one set)
    QueryCompare& operator+=(const QueryCompare& o) {
        mismatches += o.mismatches;
        not_bitwise += o.not_bitwise;
        ties += o.ties;
        near += o.near;
        return *this;
    }
};

inline QueryCompare compare_query(const std::vector<Hit>& hits, const std::vector<uint32_t>& inst,
                                  const std::vector<Hit>& ref, const std::vector<uint32_t>& ref_inst, bool any,
                                  const std::vector<Hit>& closest) {
    QueryCompare c;
    for (size_t i = 0; i < ref.size(); ++i) {
        if (std::memcmp(&hits[i], &ref[i], sizeof(Hit)) == 0 && inst[i] == ref_inst[i]) continue;
        ++c.not_bitwise;
        const bool gh = hits[i].prim != kMissPrim, ch = ref[i].prim != kMissPrim;
        bool bad = gh != ch;
        if (!bad && gh && any) {
            bad = hits[i].t < closest[i].t && ulp_distance(hits[i].t, closest[i].t) > kKernelUlpBound;
        } else if (!bad && gh) {
            if (ulp_distance(hits[i].t, ref[i].t) > kKernelUlpBound) bad = true;
            else if (hits[i].prim == ref[i].prim && inst[i] == ref_inst[i]) ++c.near;
            else ++c.ties;
        } else if (!bad) {
            bad = true;  // both miss, yet not bit for bit: a miss record's t, u or v is off
        }
        if (bad) {
            if (c.first_bad < 0) c.first_bad = int64_t(i);
            ++c.mismatches;
        }
    }
    return c;
}

}  // namespace cwbvh
