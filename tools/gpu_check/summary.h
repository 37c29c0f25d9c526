// cwbvh_gpu_check's results and its geometric-mean summaries (tools/gpu_check): the
// table rows the check fills, one function that reduces them to the means of one ray
// set, and the three summary tables printed from it (the kernels side by side, the
// two-level kernel over the flattened file's, the inline query over the CWBVH kernel).
// Host code without CUDA, so that the tests check the means on rows they make up
// (tests/tools/gpu_check_summary_test.cpp): these tables are issue 18's figures, and
// the machine that fills them has no GoogleTest.
//
// A mean: for each scene, the geometric mean over its views; then the geometric mean
// over the scenes (each scene weighted equally, whatever its number of views). A ray
// set is one bounce (0 primary, 1..kBounces diffuse) or kDiffuseAll: a view's diffuse
// bounces together, their rays over their summed kernel times. A view's ray set of
// fewer than kMinRaysForMeans rays (summed, for kDiffuseAll) is counted as left out and
// kept out of every mean; a view missing one of the set's bounces is skipped.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "cwbvh/kernels/kernel_options.h"
#include "hit_compare.h"

namespace cwbvh::gpu_check {

constexpr int kBounces = 4;
constexpr int kDiffuseAll = kBounces + 1;     ///< the ray set of diffuse bounces 1..kBounces together
constexpr size_t kMinRaysForMeans = 1000000;  ///< smaller ray sets: printed, not in the geometric means
constexpr int kKernels = 5;  ///< CWBVH, BVH2, OptiX, and the CWBVH kernel without two of its parts
/// The CWBVH kernel's A/Bs in one run, timed beside the production kernel on the same rays:
/// kNd without deferred hit distances (TraceOptions::defer_hits = false), kRn with the
/// reference node test for every ray (TraceOptions::fast_node_test = false).
constexpr int kCw = 0, kB2 = 1, kOx = 2, kNd = 3, kRn = 4;
/// The CWBVH kernel's default postponing threshold (kernel_options.h, free of CUDA).
constexpr uint32_t kDefaultPostponePercent = CwbvhKernelOptions{}.postpone_percent;

/// One kernel's result on one ray set and query.
struct KernelResult {
    bool ran = false;
    double ms = 0;  ///< median kernel time
    double mrays = 0;
    double nodes_per_ray = 0, tris_per_ray = 0;
    uint64_t mismatches = 0, hit_vs_miss = 0, ties = 0, overflows = 0, bad_indices = 0;
};

/// The two-level kernel on the instanced file, same rays (Row::tl).
struct TwoLevelResult {
    bool present = false;  ///< the scene has an instanced file (CPU reference ran)
    uint64_t cpu_hits = 0;
    double cpu_mrays = 0;
    KernelResult k;    ///< the kernel; k.mismatches: cmp.mismatches
    QueryCompare cmp;  ///< against trace_two_level_cpu (hit_compare.h, compare_query)
    /// The inline query (query.h, one thread per ray, SceneLevels::kTwoLevel) on the same
    /// file and rays; inl.mismatches: inl_cmp.mismatches against trace_two_level_cpu.
    KernelResult inl;
    QueryCompare inl_cmp;
    FlatCompare flat;   ///< against the flattened file's hits (GPU: its CWBVH kernel's)
    bool flat_gpu = false;  ///< flat compared GPU hits (else the CPU references)
};

/// One ray set (scene, view, bounce) and query.
struct Row {
    std::string scene, view, rays_kind, query;
    int bounce = 0;  ///< 0 primary, 1..kBounces diffuse
    size_t rays = 0;
    uint64_t cpu_hits = 0;
    double cpu_mrays = 0;
    KernelResult k[kKernels];  ///< [kCw] CWBVH, [kB2] BVH2, [kOx] OptiX, [kNd], [kRn] CWBVH A/Bs
    TwoLevelResult tl;         ///< the instanced file (tl.present)
    KernelResult inl;          ///< the inline query (query.h) on the same file; mismatches: inl_cmp.mismatches
    QueryCompare inl_cmp;      ///< the inline query against the CPU reference (compare_query)
    /// --postpone-sweep: the CWBVH kernel at other postponing thresholds (TraceOptions::
    /// postpone_percent), closest hit only: (percent, result).
    std::vector<std::pair<uint32_t, KernelResult>> postpone;
    /// The result at postponing threshold `percent`, or null.
    const KernelResult* at_postpone(uint32_t percent) const {
        for (const auto& [pc, result] : postpone)
            if (pc == percent) return &result;
        return nullptr;
    }
    /// Two-level kernel speed over the flattened file's CWBVH kernel's, 0 when either did not run.
    double tl_ratio() const {
        return tl.k.ran && k[kCw].ran && k[kCw].mrays > 0 ? tl.k.mrays / k[kCw].mrays : 0.0;
    }
    /// CWBVH speed over kernel `other`'s, 0 when either did not run.
    double ratio(int other = kB2) const {
        return k[kCw].ran && k[other].ran && k[other].mrays > 0 ? k[kCw].mrays / k[other].mrays : 0.0;
    }
    bool in_means() const { return rays >= kMinRaysForMeans; }
};

/// Geometric mean; 0 for none.
double geomean(const std::vector<double>& v);
/// "primary", "diffuse1".. "diffuse4", "diffuse1-4" for kDiffuseAll.
const char* kind_name(int set);
/// printf of one number, "-" when !ok.
std::string fmt(bool ok, const char* f, double v);
/// One line of a two-level vs flattened comparison.
std::string describe(const FlatCompare& c, bool any);
/// "N mismatches (a failure); M not bit for bit: T equal-t ties, U within 4 ulps, the rest
/// any-hit records of another order" (compare_query's counts).
std::string describe(const QueryCompare& c);

/// One figure over the scenes for one ray set.
struct Mean {
    size_t scenes = 0;  ///< scenes with at least one view with the figure
    double value = 0;   ///< geometric mean over them of each one's geometric mean over its views
};

/// The figures of one ray set.
template <size_t N>
struct SetMeans {
    std::array<Mean, N> mean;
    size_t left_out = 0;  ///< views whose ray set has fewer than kMinRaysForMeans rays
    /// Per figure: scene -> the values of its views that are in the means.
    std::array<std::map<std::string, std::vector<double>>, N> views;
};

/// The kernels side by side, closest hit: CWBVH Mrays/s, CWBVH/BVH2, OptiX Mrays/s,
/// CWBVH/OptiX, CWBVH over itself without deferred hits and over itself with the reference
/// node test (speeds as the set's rays over its summed kernel times). A view counts where
/// the CWBVH kernel ran on every bounce of the set; the other figures where their kernel
/// ran too.
enum KernelFigure { kCwbvhMrays, kOverBvh2, kOptixMrays, kOverOptix, kOverNoDefer, kOverRefNode };
inline constexpr size_t kKernelFigures = 6;
SetMeans<kKernelFigures> kernel_means(const std::vector<Row>& rows, int set);

/// The two-level kernel beside the flattened file's CWBVH kernel, closest hit, on views
/// where both ran: two-level Mrays/s, flattened CWBVH Mrays/s, two-level / flattened.
enum TwoLevelFigure { kTwoLevelMrays, kFlatMrays, kTwoOverFlat };
SetMeans<3> two_level_means(const std::vector<Row>& rows, int set);
/// The inline query on the two-level files over the two-level kernel, closest hit, every
/// single ray set in the means (r.tl.inl.mrays / r.tl.k.mrays; per scene the geometric mean
/// over its sets, then over the scenes); *scenes: how many; 0 when none ran.
double two_level_inline_ratio(const std::vector<Row>& rows, size_t* scenes);

/// The inline query beside the CWBVH kernel, closest hit, on views where both ran:
/// inline Mrays/s, CWBVH Mrays/s, inline / CWBVH.
enum InlineFigure { kInlineMrays, kInlineCwbvhMrays, kInlineOverCwbvh };
SetMeans<3> inline_means(const std::vector<Row>& rows, int set);

/// The CWBVH kernel at postponing threshold `percent` beside itself at the default, closest
/// hit, on views where both ran: Mrays/s at percent, default time / time at percent (> 1:
/// that threshold is faster).
enum PostponeFigure { kPostponeMrays, kPostponeOverDefault };
SetMeans<2> postpone_means(const std::vector<Row>& rows, int set, uint32_t percent);

/// The summary tables (stdout), from the functions above.
void print_summary(const std::vector<Row>& rows);
void print_two_level_summary(const std::vector<Row>& rows);
void print_inline_summary(const std::vector<Row>& rows);
void print_postpone_summary(const std::vector<Row>& rows);

}  // namespace cwbvh::gpu_check
