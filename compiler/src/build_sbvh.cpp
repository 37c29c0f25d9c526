// Spatial-split BVH (SBVH) builder: Stich, Friedrich, Dietrich, "Spatial Splits
// in Bounding Volume Hierarchies", HPG 2009. Builds down to exactly one
// triangle reference per leaf (the Ylitie et al. 2017 collapse needs it).
//
// Determinism: the output is bit-identical for any thread count because
//  - every decision is made from data whose value does not depend on the
//    schedule: boxes are min/max reductions (exact, order-free), counts are
//    integer sums, SAH costs are evaluated sequentially in a fixed order;
//  - sorts use a strict total order on references (ties are identical refs);
//  - the reference budget is handed down the tree, never shared through an
//    atomic counter;
//  - subtrees below kTaskRefs references are built by one task each, straight
//    into a block in canonical depth-first order; the blocks and the few
//    nodes above them are concatenated in that order at the end.
//
// Spatial-split binning estimates plane costs from plain-float chopped boxes
// (chop_triangle_estimate); the references' boxes of a split that is made
// always come from the conservative clip_triangle.
#include <sys/mman.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <memory>
#include <new>
#include <limits>
#include <numeric>
#include <utility>
#include <vector>

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/blocked_range.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>

#include "cwbvh/compiler/box4.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/progress.h"

namespace cwbvh::compiler {
namespace {

/// Nodes of up to this many references get a full SAH sweep over references
/// sorted by centroid (all n-1 candidate positions per axis); larger nodes use
/// kObjectBins centroid bins. Measured (dragon 871k, bunny, sponza; single
/// thread): 2048 -> 64 cut the SBVH from 4.15 s to 3.28 s on the dragon with
/// binary SAH 49.057 -> 49.054 (bunny +0.07 %, sponza -0.25 %).
constexpr size_t kSweepMaxRefs = 64;
constexpr int kObjectBins = 64;
/// Subtrees with at least this many references are built as separate tasks.
constexpr size_t kTaskRefs = 2048;
/// Binning of nodes with at least this many references runs in parallel
/// (fixed grain; the result is exact either way).
constexpr size_t kParallelBinRefs = 32768;
/// Spatial splits are not tried below this depth bound (guards against
/// pathological recursion; the reference budget also bounds them).
constexpr int kMaxSpatialDepth = 64;
/// Spatial-split pre-check (see spatial_split): an axis is binned with all
/// its bins only when binning the chopped triangles into kSpatialGateBins
/// coarse bins gives some plane a cost below (1 + kSpatialGateSlack) * the
/// object split's cost. Measured on bunny, dragon_res2, sponza (sah_binary vs
/// no pre-check): 4 bins, slack 0.1: +0.0002 / -0.0005 / -0.003 %, build_sbvh
/// instructions -60% (bunny); 4 bins, slack 0.02: +0.05 / +0.21 / +0.60 %.
/// A pre-check on the references' clipped boxes instead (no chopping) is
/// cheaper but blind to diagonal triangles: no spatial split at all on the
/// sliver test scene.
constexpr int kSpatialGateBins = 4;
constexpr double kSpatialGateSlack = 0.1;
// SbvhConfig::min_spatial_refs, measured over every shared scene
// (bench/results/quality/2026-11-25-spatial-min-refs): 16 cuts the compile's
// instructions by 21% (callgrind, dragon_res2; the small nodes' triangles span
// many bins, so their chopping is the dearest per reference) for at most +0.23%
// binary SAH, +0.19% wide SAH, -0.06% children per node and no more bytes per
// triangle on any scene (32: -30%, up to +0.59% SAH; 64: -35%, +0.73%; 8: -12%;
// 4: -5%). The collapse packs a subtree this small into one or two wide nodes
// anyway, where duplicated references buy little.
/// Upper bound of SbvhConfig::bins.
constexpr int kMaxBins = 256;
/// A spatial split that leaves one side with all of the parent's references
/// (every reference straddles the plane, e.g. a bundle of parallel slivers) is
/// allowed at most this many times on a path from the root; without a cap a
/// stack of (nearly) coincident triangles would be chopped again and again,
/// each time SAH-cheaper but never separating anything, until the budget is
/// gone. Measured on bunny: allowing 1 (or 3) such splits per path gave
/// +16% references and a WORSE final SAH (30.31 vs 30.10) than allowing none.
constexpr int kMaxNonShrinkingSpatial = 0;

/// Allocator whose allocations of at least kMinBytes bytes are each their own
/// anonymous mapping, so that freeing them returns the memory to the OS at
/// once. Through malloc, the builder's large temporaries (reference lists,
/// subtree blocks) are made and freed on TBB worker threads, stay resident
/// in those threads' malloc arenas (glibc also raises its mmap threshold
/// after each large free) and, measured on the dragon, added ~75 MB to the
/// peak. Smaller allocations (most nodes' lists) stay with malloc.
template <class T, size_t kMinBytes>
struct MappedAllocator {
    using value_type = T;
    template <class U>
    struct rebind { using other = MappedAllocator<U, kMinBytes>; };
    MappedAllocator() = default;
    template <class U>
    MappedAllocator(const MappedAllocator<U, kMinBytes>&) {}
    T* allocate(size_t n) {
        if (n * sizeof(T) < kMinBytes) return std::allocator<T>().allocate(n);
        void* p = mmap(nullptr, n * sizeof(T), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
        if (p == MAP_FAILED) throw std::bad_alloc();
        return static_cast<T*>(p);
    }
    void deallocate(T* p, size_t n) {
        if (n * sizeof(T) < kMinBytes) std::allocator<T>().deallocate(p, n);
        else munmap(p, n * sizeof(T));
    }
    template <class U>
    bool operator==(const MappedAllocator<U, kMinBytes>&) const { return true; }
};

struct Ref {
    Aabb box;
    uint32_t tri;
};
/// Reference list of one node; lists of >= 64 KiB are mapped (see MappedAllocator).
using RefList = std::vector<Ref, MappedAllocator<Ref, 65536>>;

/// Nodes of one subtree in canonical depth-first order, child indices local.
/// Blocks are freed one by one while the final array grows: always mapped.
using Block = std::vector<BinaryNode, MappedAllocator<BinaryNode, 0>>;

/// The finished tree before flattening: the top (nodes of >= kTaskRefs
/// references, split in parallel) as linked pieces, each smaller subtree as
/// one block.
struct Piece {
    BinaryNode node;                  ///< top node (child indices unset); unused for a block
    std::unique_ptr<Piece> child[2];
    Block block;                      ///< non-empty: this piece is a whole subtree
};

inline float centroid(const Ref& r, int a) { return r.box.lo[a] * 0.5f + r.box.hi[a] * 0.5f; }

/// Strict total order along axis a: centroid, then triangle id, then box.
/// References that compare equal are bitwise identical, so any sort yields the
/// same array.
struct RefLess {
    int a;
    bool operator()(const Ref& x, const Ref& y) const {
        const float cx = centroid(x, a), cy = centroid(y, a);
        if (cx != cy) return cx < cy;
        if (x.tri != y.tri) return x.tri < y.tri;
        return box_less(x, y);
    }
    /// The last key: the boxes, coordinate by coordinate.
    static bool box_less(const Ref& x, const Ref& y) {
        for (int j = 0; j < 3; ++j) {
            if (x.box.lo[j] != y.box.lo[j]) return x.box.lo[j] < y.box.lo[j];
            if (x.box.hi[j] != y.box.hi[j]) return x.box.hi[j] < y.box.hi[j];
        }
        return false;
    }
};

/// RefLess{a}'s first two keys as one integer: the centroid's bits mapped to
/// an unsigned order (after + 0.0f, which makes -0 and +0, equal centroids
/// for RefLess, the same bits), then the triangle id. key(x) < key(y) iff
/// RefLess orders x before y on those keys; equal keys leave box_less.
inline uint64_t ref_key(const Ref& r, int a) {
    const float c = centroid(r, a) + 0.0f;
    uint32_t bits;
    std::memcpy(&bits, &c, sizeof bits);
    bits = (bits & 0x80000000u) ? ~bits : (bits | 0x80000000u);
    return (uint64_t(bits) << 32) | r.tri;
}

/// Union that is safe for empty boxes. (Aabb::grow(const Aabb&) grows by the
/// two corner points, which turns an empty argument's +inf/-inf corners into
/// an infinite box; empty bins are common here.)
inline void merge(Aabb& a, const Aabb& b) {
    for (int j = 0; j < 3; ++j) {
        a.lo[j] = std::min(a.lo[j], b.lo[j]);
        a.hi[j] = std::max(a.hi[j], b.hi[j]);
    }
}

Aabb intersect(const Aabb& a, const Aabb& b) {
    Aabb r;
    for (int j = 0; j < 3; ++j) {
        r.lo[j] = std::max(a.lo[j], b.lo[j]);
        r.hi[j] = std::min(a.hi[j], b.hi[j]);
    }
    return r;
}

/// Centroid of a box in all lanes: lo * 0.5f + hi * 0.5f, as centroid().
inline F4 centroid4(const Box4& b) { return b.lo * 0.5f + b.hi * 0.5f; }

struct Bounds {
    Aabb box, centroids;
};

Bounds compute_bounds(const RefList& refs) {
    struct Acc {
        Box4 box, centroids;
        void join(const Acc& o) { box.merge(o.box); centroids.merge(o.centroids); }
    };
    auto body = [&](const tbb::blocked_range<size_t>& r, Acc b) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const Box4 box = Box4::of(refs[i].box);
            b.box.merge(box);
            b.centroids.grow(centroid4(box));
        }
        return b;
    };
    // min/max in list order (ties keep the earlier value, also across the
    // reduction's joins, which keep the ranges' order): any split of the
    // range gives the same bits.
    const Acc acc = refs.size() < kParallelBinRefs
        ? body(tbb::blocked_range<size_t>(0, refs.size()), Acc{})
        : tbb::parallel_reduce(tbb::blocked_range<size_t>(0, refs.size(), 4096), Acc{}, body,
                               [](Acc a, const Acc& b) { a.join(b); return a; });
    return Bounds{acc.box.aabb(), acc.centroids.aabb()};
}

struct Split {
    double cost = std::numeric_limits<double>::infinity();
    int axis = -1;
    enum Kind { kNone, kSweep, kBinned, kSpatial } kind = kNone;
    size_t index = 0;    // kSweep: left count; kBinned/kSpatial: first bin on the right
    Aabb left, right;    // predicted child boxes
    uint64_t nl = 0, nr = 0;
    float plane = 0.0f;               // kSpatial: split plane
    float bin_lo = 0.0f, bin_scale = 0.0f;  // kBinned: centroid binning parameters
};

// ---------------------------------------------------------------------------
// Object splits
// ---------------------------------------------------------------------------

/// Full SAH sweep over references sorted by centroid along each axis. Ties in
/// cost go to the position nearest the middle, which makes the split of
/// identical references a median split (no degenerate 1 : n-1 chains).
/// `at(a, i)`: the i-th of the n references in RefLess{a} order. One home for
/// both callers: sweep_object_split (sorts per node) and the sorted small
/// subtrees (SmallSet, sorted once).
template <class At>
Split sweep_sorted(size_t n, At&& at) {
    Split best;
    // Scratch reused across nodes (nothing in here waits on TBB, so no other
    // task can run on this thread while it is in use).
    static thread_local std::vector<double> right_area;
    static thread_local std::vector<Box4> right_box;
    right_area.resize(n);
    right_box.resize(n);
    Box4 best_left, best_right;  // converted to best.left/right once, at the end
    for (int a = 0; a < 3; ++a) {
        Box4 acc;
        for (size_t i = n; i-- > 1;) {  // right_box[i] = union of sorted[i..n)
            acc.merge(Box4::of(at(a, i).box));
            right_box[i] = acc;
            right_area[i] = acc.half_area();
        }
        Box4 left;
        const double half = double(n) / 2.0;
        for (size_t k = 1; k < n; ++k) {  // left = sorted[0..k)
            left.merge(Box4::of(at(a, k - 1).box));
            const double cost = left.half_area() * double(k) + right_area[k] * double(n - k);
            const bool better = cost < best.cost ||
                (cost == best.cost && best.axis == a &&
                 std::fabs(double(k) - half) < std::fabs(double(best.index) - half));
            if (better) {
                best.cost = cost;
                best.axis = a;
                best.kind = Split::kSweep;
                best.index = k;
                best_left = left;
                best_right = right_box[k];
                best.nl = k;
                best.nr = n - k;
            }
        }
    }
    if (best.axis >= 0) {
        best.left = best_left.aabb();
        best.right = best_right.aabb();
    }
    return best;
}

/// The sweep for a node of any size: sorts the references along each axis
/// and leaves the best axis' order in best_sorted (RefLess is a strict total
/// order: the same array a fresh sort would give).
Split sweep_object_split(const RefList& refs, RefList& best_sorted) {
    static thread_local RefList sorted[3];  // scratch, see sweep_sorted
    for (int a = 0; a < 3; ++a) {
        sorted[a].assign(refs.begin(), refs.end());
        std::sort(sorted[a].begin(), sorted[a].end(), RefLess{a});
    }
    const Split best = sweep_sorted(refs.size(), [&](int a, size_t i) -> const Ref& { return sorted[a][i]; });
    if (best.axis >= 0) best_sorted.assign(sorted[best.axis].begin(), sorted[best.axis].end());
    return best;
}

/// The SAH sweep over bins shared by every split search: for each plane
/// b = 1..n-1 (between bins b-1 and b) calls f(b, left, nl, right, nr), with
/// left / nl the union of lbox[0..b) / sum of lcnt[0..b) and right / nr the
/// union of rbox[b..n) / sum of rcnt[b..n); planes with an empty side are
/// skipped. Unions are min/max (exact), sums integer: deterministic.
template <class F>
void sweep_bins(int n, const Box4* lbox, const uint32_t* lcnt, const Box4* rbox, const uint32_t* rcnt, F&& f) {
    static thread_local std::vector<Box4> right;  // scratch; f never waits on TBB
    static thread_local std::vector<uint64_t> nright;
    right.resize(size_t(n));
    nright.resize(size_t(n));
    Box4 acc;
    uint64_t cnt = 0;
    for (int b = n - 1; b >= 1; --b) {
        acc.merge(rbox[b]);
        cnt += rcnt[b];
        right[size_t(b)] = acc;
        nright[size_t(b)] = cnt;
    }
    Box4 left;
    uint64_t nl = 0;
    for (int b = 1; b < n; ++b) {
        left.merge(lbox[b - 1]);
        nl += lcnt[b - 1];
        if (nl == 0 || nright[size_t(b)] == 0) continue;
        f(b, left, nl, right[size_t(b)], nright[size_t(b)]);
    }
}

struct ObjectBins {
    Box4 box[kObjectBins];
    uint32_t count[kObjectBins] = {};
    void join(const ObjectBins& o) {
        for (int b = 0; b < kObjectBins; ++b) { box[b].merge(o.box[b]); count[b] += o.count[b]; }
    }
};

/// Bin of a centroid: float arithmetic, the same expression for binning and
/// partitioning so the two always agree.
inline int object_bin(float c, float lo, float scale) {
    const int b = int((c - lo) * scale);
    return std::clamp(b, 0, kObjectBins - 1);
}

/// The three axes' centroid bins, filled in one pass over the references.
struct ObjectBins3 {
    ObjectBins axis[3];
    void join(const ObjectBins3& o) {
        for (int a = 0; a < 3; ++a) axis[a].join(o.axis[a]);
    }
};

Split binned_object_split(const RefList& refs, const Aabb& cbox) {
    Split best;
    const size_t n = refs.size();
    bool use[3];
    float lo[3], scale[3];
    for (int a = 0; a < 3; ++a) {
        const float ext = cbox.hi[a] - cbox.lo[a];
        use[a] = ext > 0.0f && std::isfinite(ext);
        scale[a] = use[a] ? float(kObjectBins) * 0.99999f / ext : 0.0f;
        lo[a] = cbox.lo[a];
    }
    // object_bin() for the three axes at once: the same float operations per
    // lane (truncation of out-of-range values gives INT_MIN either way, then
    // the clamp). Unused axes are binned too and ignored.
    const F4 lo4 = {lo[0], lo[1], lo[2], lo[2]}, scale4 = {scale[0], scale[1], scale[2], scale[2]};
    auto body = [&](const tbb::blocked_range<size_t>& r, ObjectBins3 bins) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const Box4 box = Box4::of(refs[i].box);
            const F4 f = (centroid4(box) - lo4) * scale4;
            int b[4];
#if defined(__SSE2__)
            const __m128i top = _mm_set1_epi32(kObjectBins - 1);
            __m128i bi = _mm_cvttps_epi32(__m128(f));
            bi = _mm_andnot_si128(_mm_cmplt_epi32(bi, _mm_setzero_si128()), bi);       // < 0 -> 0
            const __m128i over = _mm_cmpgt_epi32(bi, top);
            bi = _mm_or_si128(_mm_and_si128(over, top), _mm_andnot_si128(over, bi));  // > 63 -> 63
            _mm_storeu_si128(reinterpret_cast<__m128i*>(b), bi);
#else
            for (int a = 0; a < 3; ++a) b[a] = std::clamp(int(f[a]), 0, kObjectBins - 1);
#endif
            for (int a = 0; a < 3; ++a) {
                bins.axis[a].box[b[a]].merge(box);
                ++bins.axis[a].count[b[a]];
            }
        }
        return bins;
    };
    const ObjectBins3 bins = n < kParallelBinRefs
        ? body(tbb::blocked_range<size_t>(0, n), ObjectBins3{})
        : tbb::parallel_reduce(tbb::blocked_range<size_t>(0, n, 4096), ObjectBins3{}, body,
                               [](ObjectBins3 x, const ObjectBins3& y) { x.join(y); return x; });
    for (int a = 0; a < 3; ++a) {
        if (!use[a]) continue;
        const ObjectBins& ab = bins.axis[a];
        sweep_bins(kObjectBins, ab.box, ab.count, ab.box, ab.count,
                   [&](int b, const Box4& left, uint64_t nl, const Box4& right, uint64_t nr) {
                       const double cost = left.half_area() * double(nl) + right.half_area() * double(nr);
                       if (cost < best.cost) {
                           best = Split{cost,   a,  Split::kBinned, size_t(b), left.aabb(), right.aabb(),
                                        nl,     nr, 0.0f,           lo[a],     scale[a]};
                       }
                   });
    }
    return best;
}

// ---------------------------------------------------------------------------
// Spatial splits (Stich et al. 2009, section 4.3)
// ---------------------------------------------------------------------------

/// Spatial-split bins. Unions are min/max and counts integer sums, so the
/// join order does not matter. reset() reuses the storage (serial passes keep
/// one per thread: no allocation per node).
struct SpatialBins {
    std::vector<Box4> box;
    std::vector<uint32_t> enter, exit;
    explicit SpatialBins(int n = 0) { reset(n); }
    void reset(int n) {
        box.assign(size_t(n), Box4{});
        enter.assign(size_t(n), 0);
        exit.assign(size_t(n), 0);
    }
    void join(const SpatialBins& o) {
        for (size_t b = 0; b < box.size(); ++b) {
            box[b].merge(o.box[b]);
            enter[b] += o.enter[b];
            exit[b] += o.exit[b];
        }
    }
};

/// lower_bound_bins's bins (see candidate_planes): boxes by a reference's last and first bin.
struct LowerBoundBins {
    std::vector<Box4> by_last, by_first;
    std::vector<uint32_t> enter, exit;
    explicit LowerBoundBins(int n = 0) { reset(n); }
    void reset(int n) {
        by_last.assign(size_t(n), Box4{});
        by_first.assign(size_t(n), Box4{});
        enter.assign(size_t(n), 0);
        exit.assign(size_t(n), 0);
    }
    void join(const LowerBoundBins& o) {
        for (size_t b = 0; b < by_last.size(); ++b) {
            by_last[b].merge(o.by_last[b]);
            by_first[b].merge(o.by_first[b]);
            enter[b] += o.enter[b];
            exit[b] += o.exit[b];
        }
    }
};

/// Bins `n` references: fill(begin, end, bins) serially into this thread's
/// scratch below kParallelBinRefs, else as a TBB reduction (exact either way).
template <class Bins, class Fill>
const Bins& bin_references(size_t n, int nbins, Fill&& fill, Bins& result) {
    if (n < kParallelBinRefs) {
        static thread_local Bins scratch;  // no task switch while in use: fill never waits on TBB
        scratch.reset(nbins);
        fill(size_t(0), n, scratch);
        return scratch;
    }
    result = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, n, 4096), Bins(nbins),
        [&](const tbb::blocked_range<size_t>& r, Bins bins) { fill(r.begin(), r.end(), bins); return bins; },
        [](Bins x, const Bins& y) { x.join(y); return x; });
    return result;
}

/// Bin planes along one axis: p[0] = lo, p[B] = hi, evenly spaced in
/// between (double arithmetic rounded to nearest; made monotone), and the
/// factor that maps a coordinate to a first guess of its bin.
struct BinPlanes {
    float p[kMaxBins + 1];  // p[0..bins]; no heap allocation per pass
    float q[kMaxBins + 1];  // p with q[0] = -inf, q[bins] = +inf: bin b is [q[b], q[b+1])
    int count = 0;          // bins
    float scale = 0.0f;     // ~bins / (hi - lo) (a guess's factor only); 0 for a zero-width range
    int bins() const { return count; }
    const float* data() const { return p; }
    float operator[](int i) const { return p[i]; }
};
BinPlanes bin_planes(float lo, float hi, int bins) {
    BinPlanes bp;
    float* p = bp.p;
    bp.count = bins;
    p[0] = lo;
    p[bins] = hi;
    for (int i = 1; i < bins; ++i) {
        p[i] = float(double(lo) + (double(hi) - double(lo)) * double(i) / double(bins));
        p[i] = std::clamp(p[i], p[i - 1], hi);
    }
    const float inf = std::numeric_limits<float>::infinity();
    std::copy(p, p + bins + 1, bp.q);
    bp.q[0] = -inf;
    bp.q[bins] = inf;
    const double width = double(hi) - double(lo);
    // May round to inf for a width of a few denormals: bin_guess clamps.
    bp.scale = width > 0.0 ? float(double(bins) / width) : 0.0f;
    return bp;
}

/// First guess of the bin of x (any value in 0..bins-1); bin_of_lo/hi then
/// step to the exact answer, which is defined by the planes alone, so the
/// guess may be off by rounding (float arithmetic: the dearest part of the
/// spatial-split search was this function in double).
inline int bin_guess(const BinPlanes& p, float x) {
    float g = (x - p[0]) * p.scale;
    g = g > 0.0f ? g : 0.0f;  // also NaN (inf * 0)
    const float top = float(p.bins() - 1);
    return int(g < top ? g : top);
}
/// Bin of a lower bound: plane[b] <= x < plane[b+1] (clamped to the bins),
/// i.e. the number of inner planes plane[1..bins-1] that are <= x.
inline int bin_of_lo(const BinPlanes& p, float x) {
    const int bins = p.bins();
    int b = bin_guess(p, x);
    // The usual case, the guess is right: the loops' condition with the outer
    // planes as -inf / +inf.
    if (p.q[b] <= x && x < p.q[b + 1]) return b;
    while (b > 0 && p[b] > x) --b;
    while (b < bins - 1 && p[b + 1] <= x) ++b;
    return b;
}
/// Bin of an upper bound: plane[b] < x <= plane[b+1], so a reference that only
/// touches a plane from the left is not counted in the bin right of it; the
/// number of inner planes that are < x.
inline int bin_of_hi(const BinPlanes& p, float x) {
    const int bins = p.bins();
    int b = bin_guess(p, x);
    if (p.q[b] < x && x <= p.q[b + 1]) return b;  // the guess is right
    while (b > 0 && p[b] >= x) --b;
    while (b < bins - 1 && p[b + 1] < x) ++b;
    return b;
}

/// A reference's first and last bin along one axis (bins <= kMaxBins).
struct BinSpan {
    uint8_t first, last;
};
static_assert(kMaxBins <= 256, "BinSpan holds bin indices in 8 bits");

/// When every coarse plane is a fine plane, coarse[i] == fine[i << shift]
/// (bit-equal floats), a value's coarse bin is its fine bin >> shift: bin_of_lo
/// counts the inner planes <= x, and for non-decreasing planes those form a
/// prefix fine[1..k], of which fine[(1..) << shift] are the coarse ones; the
/// same holds for bin_of_hi (planes < x) and for max(). Returns that shift,
/// or -1 (bin afresh). bin_planes computes plane i of B bins as
/// lo + (hi-lo)*i/B in double, and scaling i and B by a power of two scales
/// the exact product and quotient without changing their rounding, so with
/// 32 bins and 4 coarse ones the planes do coincide; the check makes the
/// result independent of that argument.
int coarse_shift(const BinPlanes& fine, const BinPlanes& coarse) {
    int shift = 0;
    while ((coarse.bins() << shift) < fine.bins()) ++shift;
    if ((coarse.bins() << shift) != fine.bins()) return -1;
    for (int i = 0; i <= coarse.bins(); ++i)
        if (!(coarse[i] == fine[i << shift])) return -1;
    return shift;
}

class Builder {
public:
    Builder(const Scene& scene, const SbvhConfig& config, Progress* progress)
        : scene_(scene), config_(config), progress_(progress) {}

    /// Root of the build: the task-parallel top of the tree as pieces.
    std::unique_ptr<Piece> build(RefList& refs, uint64_t budget) {
        return build_piece(refs, budget, 0, 0, scene_.triangle_count());
    }
    /// The same over references that are not triangles of scene_ (build_boxes):
    /// budget 0, so no spatial split ever reads a triangle.
    std::unique_ptr<Piece> build_object_only(RefList& refs) { return build_piece(refs, 0, 0, 0, refs.size()); }

    uint64_t spatial_splits() const { return spatial_splits_.load(); }
    uint64_t object_splits() const { return object_splits_.load(); }

private:
    /// Children of one split node, and what they inherit.
    struct Children {
        RefList left, right;
        uint64_t budget_left = 0, budget_right = 0;
        int chops = 0;
    };

    /// Decides node `refs`: returns false for a leaf (one reference), else
    /// partitions the references into `kids`. `box` gets the node's bounds.
    /// `refs` is released either way. `chops`: non-shrinking spatial splits
    /// on the path from the root.
    bool split_node(RefList& refs, uint64_t budget, int depth, int chops, Aabb& box, Children& kids) {
        const size_t n = refs.size();
        const Bounds bounds = compute_bounds(refs);
        box = bounds.box;
        if (n == 1) return false;
        if (depth == 0) root_area_ = bounds.box.half_area();

        // 1. Best object split: full sweep for small nodes or when the
        //    centroids do not spread (identical references), bins otherwise.
        Split object;
        RefList sorted;  // sweep: the references in the best axis' order
        if (n > kSweepMaxRefs) object = binned_object_split(refs, bounds.centroids);
        if (object.kind == Split::kNone) object = sweep_object_split(refs, sorted);

        // 2. Spatial split, else the object split.
        if (!try_spatial(object, bounds.box, budget, depth, chops, [&]() -> const RefList& { return refs; }, kids)) {
            object_partition(refs, sorted, object, kids.left, kids.right);
            object_splits_.fetch_add(1, std::memory_order_relaxed);
        }
        share_budget_of_lists(n, budget, chops, kids);
        RefList().swap(refs);  // free the parent's list before recursing
        return true;
    }

    /// Spatial split (Stich et al. 2009, section 4.5), only where the object
    /// split's children overlap by more than alpha * A(root) and the subtree
    /// still has reference budget. On success the references are in kids.left
    /// and kids.right. `refs()` gives the node's references in list order
    /// (spatial_partition's unsplitting depends on it); it is called only when
    /// the overlap test passes.
    template <class GetRefs>
    bool try_spatial(const Split& object, const Aabb& box, uint64_t budget, int depth, int chops, GetRefs&& refs,
                     Children& kids) {
        // Bitwise equal child boxes: the references coincide (duplicated
        // triangles); chopping them never separates anything.
        const bool coincident = std::memcmp(&object.left, &object.right, sizeof(Aabb)) == 0;
        if (object.nl + object.nr < config_.min_spatial_refs || budget == 0 || depth >= kMaxSpatialDepth ||
            !(root_area_ > 0.0) || coincident)
            return false;
        const double overlap = intersect(object.left, object.right).half_area();
        if (!(overlap > double(config_.split_alpha) * root_area_)) return false;
        const RefList& list = refs();
        const Split spatial = spatial_split(list, box, object.cost);
        if (!(spatial.cost < object.cost) ||
            !spatial_partition(list, spatial, object.cost, budget, chops < kMaxNonShrinkingSpatial,
                               kids.left, kids.right))
            return false;
        spatial_splits_.fetch_add(1, std::memory_order_relaxed);
        return true;
    }

    /// Budget: duplicates made here are paid for; the rest is shared in
    /// proportion to the sum of the children's reference box areas (wl, wr:
    /// summed in each child's list order): spatial splits pay off where
    /// references are large for their node (floors, walls), not where a dense
    /// mesh has many small triangles. Measured at growth 0.2 against sharing
    /// by reference count (binary SAH): fg_cg57 29.88 -> 29.07, torcs 11.85 ->
    /// 11.83, iceland 27.63 -> 27.47, sponza 62.35 -> 62.59 (unlimited: 28.45,
    /// 11.61, 27.24, 61.32). Deterministic: sums in list order, one rounding.
    static void share_budget(uint64_t n, uint64_t nl, uint64_t nr, uint64_t budget, int chops, double wl, double wr,
                             Children& kids) {
        const uint64_t both = nl + nr;
        const uint64_t dup = both - n;
        const uint64_t rest = budget - dup;  // spatial_partition ensured dup <= budget
        const double share = wl + wr > 0.0 ? wl / (wl + wr) : double(nl) / double(both);
        kids.budget_left = std::min<uint64_t>(rest, uint64_t(std::floor(double(rest) * share)));
        kids.budget_right = rest - kids.budget_left;
        kids.chops = chops + ((nl == n || nr == n) ? 1 : 0);
    }

    /// share_budget with the children's lists as made (sums in list order).
    static void share_budget_of_lists(uint64_t n, uint64_t budget, int chops, Children& kids) {
        double wl = 0.0, wr = 0.0;
        for (const Ref& r : kids.left) wl += Box4::of(r.box).half_area();  // = Aabb::half_area, faster
        for (const Ref& r : kids.right) wr += Box4::of(r.box).half_area();
        share_budget(n, kids.left.size(), kids.right.size(), budget, chops, wl, wr, kids);
    }

    /// Top of the tree: nodes of at least kTaskRefs references; their two
    /// children are built as parallel tasks. Smaller subtrees become blocks.
    /// `weight`: the piece's share of the progress units (the root has the
    /// scene's triangle count; a split hands it on in proportion to the
    /// children's references, remainder to the right), added when its block
    /// is done, so the blocks add up to the triangle count exactly however
    /// many references the spatial splits make. Never read by the build.
    std::unique_ptr<Piece> build_piece(RefList& refs, uint64_t budget, int depth, int chops, uint64_t weight) {
        auto piece = std::make_unique<Piece>();
        if (refs.size() < kTaskRefs) {
            piece->block.reserve(2 * refs.size() - 1);  // exact without spatial splits
            build_block(piece->block, refs, budget, depth, chops);
            progress_add(progress_, weight);  // one relaxed atomic per block (< kTaskRefs references)
            return piece;
        }
        Children kids;
        if (!split_node(refs, budget, depth, chops, piece->node.box, kids)) {  // unreachable: n >= 2
            progress_add(progress_, weight);
            return piece;
        }
        // weight <= triangles < 2^30 and nl < 2^32: the product fits in 64 bits.
        const uint64_t nl = kids.left.size(), nr = kids.right.size();
        const uint64_t weight_left = weight * nl / (nl + nr);
        tbb::task_group g;
        g.run([&] { piece->child[0] = build_piece(kids.left, kids.budget_left, depth + 1, kids.chops, weight_left); });
        piece->child[1] = build_piece(kids.right, kids.budget_right, depth + 1, kids.chops, weight - weight_left);
        g.wait();
        return piece;
    }

    /// A subtree built by one task straight into `out`, in canonical
    /// depth-first order (left subtree first); returns the node's index.
    uint32_t build_block(Block& out, RefList& refs, uint64_t budget, int depth, int chops) {
        if (refs.size() <= kSweepMaxRefs) return build_small_root(out, refs, budget, depth, chops);
        const uint32_t index = uint32_t(out.size());
        out.emplace_back();
        const uint32_t prim = refs.size() == 1 ? refs[0].tri : kInvalidIndex;
        Aabb box;
        Children kids;
        const bool internal = split_node(refs, budget, depth, chops, box, kids);
        out[index].box = box;  // (out may have moved: index, not reference)
        if (!internal) {
            out[index].set_prim(prim);
            return index;
        }
        const uint32_t l = build_block(out, kids.left, kids.budget_left, depth + 1, kids.chops);
        const uint32_t r = build_block(out, kids.right, kids.budget_right, depth + 1, kids.chops);
        out[index].child[0] = l;
        out[index].child[1] = r;
        return index;
    }

    /// Subtrees of at most kSweepMaxRefs references, where every node takes
    /// the full sweep: the references are sorted along each axis once, at the
    /// small subtree's root, and each object split stable-partitions the three
    /// orders. That gives exactly the orders a sort of each child would
    /// (RefLess is a strict total order), so the tree is the one per-node
    /// sorting builds, for a fraction of the sorting (dragon: 902k sweep nodes
    /// in 52k small subtrees). A spatial split makes new references: each of
    /// its children is the root of a new small subtree.
    struct SmallSet {
        const Ref* refs;        ///< the small subtree's references
        uint8_t* order[3];      ///< this node's references (indices into refs) in RefLess{axis} order
        const uint8_t* list;    ///< this node's references in list order (the order split_node would see)
        size_t n;
    };
    static_assert(kSweepMaxRefs <= 256, "SmallSet indices are 8-bit");

    uint32_t build_small_root(Block& out, RefList& refs, uint64_t budget, int depth, int chops) {
        const size_t n = refs.size();
        Ref local[kSweepMaxRefs];
        std::copy(refs.begin(), refs.end(), local);
        RefList().swap(refs);  // free the parent's list before recursing
        uint8_t order[4][kSweepMaxRefs];
        for (size_t i = 0; i < n; ++i) order[3][i] = uint8_t(i);  // list order: as handed down
        uint64_t key[kSweepMaxRefs];
        for (int a = 0; a < 3; ++a) {  // RefLess{a} order, its keys computed once per reference
            for (size_t i = 0; i < n; ++i) key[i] = ref_key(local[i], a);
            std::copy(order[3], order[3] + n, order[a]);
            std::sort(order[a], order[a] + n, [&](uint8_t x, uint8_t y) {
                return key[x] != key[y] ? key[x] < key[y] : RefLess::box_less(local[x], local[y]);
            });
        }
        return build_small(out, SmallSet{local, {order[0], order[1], order[2]}, order[3], n}, budget, depth, chops);
    }

    /// build_block for a SmallSet: the same decisions as split_node, in the
    /// same order, on the presorted references.
    uint32_t build_small(Block& out, const SmallSet& s, uint64_t budget, int depth, int chops) {
        const uint32_t index = uint32_t(out.size());
        out.emplace_back();
        const size_t n = s.n;
        Box4 box4;
        for (size_t i = 0; i < n; ++i) box4.merge(Box4::of(s.refs[s.order[0][i]].box));
        const Aabb box = box4.aabb();
        out[index].box = box;
        if (n == 1) {
            out[index].set_prim(s.refs[s.order[0][0]].tri);
            return index;
        }
        if (depth == 0) root_area_ = box.half_area();
        if (n == 2 && n < config_.min_spatial_refs) {
            // What the sweep decides for two references, without it: every
            // axis costs A(first) + A(second) (the same sum in either order,
            // finite boxes), and sweep_sorted breaks an equal cost only within
            // the axis that holds the best, so axis 0 keeps the split and its
            // first reference (RefLess{0} order) goes left.
            object_splits_.fetch_add(1, std::memory_order_relaxed);
            const SmallSet ls{s.refs, {s.order[0], s.order[0], s.order[0]}, s.order[0], 1};
            const SmallSet rs{s.refs, {s.order[0] + 1, s.order[0] + 1, s.order[0] + 1}, s.order[0] + 1, 1};
            const uint32_t l = build_small(out, ls, 0, depth + 1, chops);
            const uint32_t r = build_small(out, rs, 0, depth + 1, chops);
            out[index].child[0] = l;
            out[index].child[1] = r;
            return index;
        }
        const Split object = sweep_sorted(n, [&](int a, size_t i) -> const Ref& { return s.refs[s.order[a][i]]; });
        Children kids;
        RefList list;
        // Below min_spatial_refs neither this node nor any node under it (its
        // object splits only make smaller ones) tries a spatial split
        // (try_spatial's first test): the budget and the chops are never read
        // again, so they are not shared out (no box areas summed).
        const bool spatial_possible = n >= config_.min_spatial_refs;
        const bool spatial = spatial_possible && try_spatial(object, box, budget, depth, chops, [&]() -> const RefList& {
            list.resize(n);
            for (size_t i = 0; i < n; ++i) list[i] = s.refs[s.list[i]];
            return list;
        }, kids);
        if (spatial) {
            RefList().swap(list);
            share_budget_of_lists(n, budget, chops, kids);
            const uint32_t l = build_block(out, kids.left, kids.budget_left, depth + 1, kids.chops);
            const uint32_t r = build_block(out, kids.right, kids.budget_right, depth + 1, kids.chops);
            out[index].child[0] = l;
            out[index].child[1] = r;
            return index;
        }
        object_splits_.fetch_add(1, std::memory_order_relaxed);
        // Object split: the first k along the best axis go left (the old
        // partition's `left`, in the same order, hence the same sums).
        const int best = object.axis;
        const size_t k = object.index;
        bool goes_left[kSweepMaxRefs];
        for (size_t i = 0; i < n; ++i) goes_left[s.order[best][i]] = i < k;
        for (int a = 0; a < 3; ++a) {
            if (a == best) continue;
            uint8_t right[kSweepMaxRefs];
            size_t nl = 0, nr = 0;
            for (size_t i = 0; i < n; ++i) {  // without branches: goes_left is data
                const uint8_t r = s.order[a][i];
                const size_t gl = goes_left[r];
                s.order[a][nl] = r;  // nl <= i: never overwrites an unread entry
                right[nr] = r;
                nl += gl;
                nr += 1 - gl;
            }
            std::copy(right, right + nr, s.order[a] + nl);
        }
        if (spatial_possible) {
            double wl = 0.0, wr = 0.0;
            for (size_t i = 0; i < k; ++i) wl += Box4::of(s.refs[s.order[best][i]].box).half_area();
            for (size_t i = k; i < n; ++i) wr += Box4::of(s.refs[s.order[best][i]].box).half_area();
            share_budget(n, k, n - k, budget, chops, wl, wr, kids);
        }
        const SmallSet ls{s.refs, {s.order[0], s.order[1], s.order[2]}, s.order[best], k};
        const SmallSet rs{s.refs, {s.order[0] + k, s.order[1] + k, s.order[2] + k}, s.order[best] + k, n - k};
        const uint32_t l = build_small(out, ls, kids.budget_left, depth + 1, kids.chops);
        const uint32_t r = build_small(out, rs, kids.budget_right, depth + 1, kids.chops);
        out[index].child[0] = l;
        out[index].child[1] = r;
        return index;
    }

    void object_partition(const RefList& refs, const RefList& sorted, const Split& s,
                          RefList& left, RefList& right) {
        if (s.kind == Split::kSweep) {
            left.assign(sorted.begin(), sorted.begin() + ptrdiff_t(s.index));
            right.assign(sorted.begin() + ptrdiff_t(s.index), sorted.end());
            return;
        }
        // Binned: the same bin function and parameters as binned_object_split.
        const int a = s.axis;
        left.clear();
        right.clear();
        left.reserve(s.nl);
        right.reserve(s.nr);
        for (const Ref& r : refs) {
            if (object_bin(centroid(r, a), s.bin_lo, s.bin_scale) < int(s.index)) left.push_back(r);
            else right.push_back(r);
        }
    }

    /// Best spatial split (Stich et al. 2009, section 4.3), or none.
    ///
    /// Pruning per axis, cheapest first: (1) candidate_planes, from the
    /// references' boxes alone, finds the planes where the object split may
    /// be beaten; none: the axis is skipped. It bounds the binned estimate
    /// below only up to rounding, so in principle it can skip a plane whose
    /// estimate was marginally better; measured: identical trees on sponza,
    /// fg_cg57, dragon_res2, dragon; dragon SBVH 3.30 -> 2.70-2.84 s single
    /// thread. It never affects correctness: the references of a split that
    /// is made always come from clip_triangle. (2) The coarse pre-check
    /// below, whose chopped parts then narrow the candidate planes. (3) The
    /// full pass bins with the planes outside the candidates merged away, so
    /// a triangle is chopped only at candidate planes (dragon: the candidates
    /// are ~20% of the planes of an axis that gets a full pass; SBVH at 2
    /// threads 0.85 -> 0.73 s, every shared scene's file byte-identical at 1
    /// and 2 threads).
    ///
    /// Pre-check per axis: chopping triangles is ~90% of the spatial-split
    /// binning, and at most nodes no plane beats the object split (bunny:
    /// 63k nodes try, 87 spatial splits are made). The axis is first binned
    /// into kSpatialGateBins coarse bins (a reference then spans 1-2 bins, so
    /// few chops); only where some coarse plane comes within
    /// kSpatialGateSlack of the object split's cost is it binned again with
    /// the full bin count. Deterministic: a function of the node's references.
    Split spatial_split(const RefList& refs, const Aabb& box, double object_cost) {
        Split best;
        const size_t n = refs.size();
        // Small nodes get fewer bins (2n, at least 4): the binning cost is
        // n * bins clipped slabs per axis, and a handful of references gains
        // nothing from 32 candidate planes. Depends only on n: deterministic.
        const int nb = int(std::min<size_t>(size_t(config_.bins), std::max<size_t>(4, 2 * n)));
        // Each reference's first and last bin along the axis, found once by
        // the lower bound and reused by both binning passes (see coarse_shift).
        // Serial nodes use this thread's scratch (nothing below waits on TBB);
        // parallel ones their own array.
        static thread_local std::vector<BinSpan> span_scratch;
        std::vector<BinSpan> span_large;
        std::vector<BinSpan>& spans = n < kParallelBinRefs ? span_scratch : span_large;
        if (spans.size() < n) spans.resize(n);
        for (int a = 0; a < 3; ++a) {
            if (!(box.hi[a] > box.lo[a])) continue;
            const BinPlanes fine = bin_planes(box.lo[a], box.hi[a], nb);
            // Exact-enough pruning first: the planes that may beat the object split.
            LowerBoundBins lb_storage;
            const LowerBoundBins& lb = lower_bound_bins(refs, a, fine, spans.data(), lb_storage);
            PlaneWindow window = candidate_planes(lb, nullptr, nb, 0, 0, object_cost);
            if (window.empty()) continue;
            // Coarse pre-check (few bins anyway: none).
            const int nc = std::min(nb, kSpatialGateBins);
            if (nc < nb) {
                const BinPlanes coarse = bin_planes(box.lo[a], box.hi[a], nc);
                const int shift = coarse_shift(fine, coarse);
                SpatialBins storage;
                const SpatialBins& bins = bin_references(n, nc, [&](size_t begin, size_t end, SpatialBins& out) {
                    for (size_t i = begin; i != end; ++i) {
                        int b0, b1;
                        if (shift >= 0) {
                            b0 = spans[i].first >> shift;
                            b1 = spans[i].last >> shift;
                        } else {  // the coarse planes are not fine planes: bin afresh
                            b0 = bin_of_lo(coarse, refs[i].box.lo[a]);
                            b1 = std::max(b0, bin_of_hi(coarse, refs[i].box.hi[a]));
                        }
                        bin_reference(refs[i], a, coarse.data(), b0, b1, out);
                    }
                }, storage);
                double gate_cost = std::numeric_limits<double>::infinity();
                // Entering counts on the left, exiting counts on the right of each plane.
                sweep_bins(nc, bins.box.data(), bins.enter.data(), bins.box.data(), bins.exit.data(),
                           [&](int b, const Box4& left, uint64_t nl, const Box4& right, uint64_t nr) {
                               if (!(coarse[b] > coarse[0] && coarse[b] < coarse[nc])) return;
                               const double cost = left.half_area() * double(nl) + right.half_area() * double(nr);
                               gate_cost = std::min(gate_cost, cost);
                           });
                if (!(gate_cost < (1.0 + kSpatialGateSlack) * object_cost)) continue;
                // The coarse parts tighten the bound at every fine plane.
                if (shift >= 0) window = candidate_planes(lb, &bins, nb, nc, shift, object_cost);
                if (window.empty()) continue;
            }
            // All bins, with the planes outside the window merged away: the
            // bins below window.lo become one, and those from window.hi on.
            float planes[kMaxBins + 1];
            const int k = window.hi - window.lo + 1;  // candidate planes
            const int m = k + 1;                       // bins
            planes[0] = fine[0];
            std::copy(fine.data() + window.lo, fine.data() + window.hi + 1, planes + 1);
            planes[m] = fine[nb];
            const auto bin_of_fine = [&](int f) {
                return f < window.lo ? 0 : f >= window.hi ? m - 1 : f - window.lo + 1;
            };
            SpatialBins storage;
            const SpatialBins& bins = bin_references(n, m, [&](size_t begin, size_t end, SpatialBins& out) {
                for (size_t i = begin; i != end; ++i)
                    bin_reference(refs[i], a, planes, bin_of_fine(spans[i].first), bin_of_fine(spans[i].last), out);
            }, storage);
            sweep_bins(m, bins.box.data(), bins.enter.data(), bins.box.data(), bins.exit.data(),
                       [&](int b, const Box4& left, uint64_t nl, const Box4& right, uint64_t nr) {
                           if (!(planes[b] > planes[0] && planes[b] < planes[m])) return;
                           const double cost = left.half_area() * double(nl) + right.half_area() * double(nr);
                           if (cost < best.cost) {
                               best = Split{cost, a,  Split::kSpatial, size_t(window.lo + b - 1), left.aabb(),
                                            right.aabb(), nl, nr, planes[b]};
                           }
                       });
        }
        return best;
    }

    /// Candidate planes of one axis: fine planes lo..hi (1..bins-1), empty when lo > hi.
    struct PlaneWindow {
        int lo = 0, hi = -1;
        bool empty() const { return lo > hi; }
    };

    /// Boxes and counts of a lower bound on every spatial split plane of
    /// `planes` along axis a, without chopping any triangle (see
    /// candidate_planes). Writes every reference's first and last bin
    /// (bin_of_lo, then bin_of_hi raised to at least the first) to spans[0..n).
    const LowerBoundBins& lower_bound_bins(const RefList& refs, int a, const BinPlanes& planes, BinSpan* spans,
                                           LowerBoundBins& storage) const {
        return bin_references(
            refs.size(), planes.bins(),
            [&](size_t begin, size_t end, LowerBoundBins& out) {
                for (size_t i = begin; i != end; ++i) {
                    const Aabb& box = refs[i].box;
                    const int b0 = bin_of_lo(planes, box.lo[a]);
                    const int b1 = std::max(b0, bin_of_hi(planes, box.hi[a]));
                    spans[i] = BinSpan{uint8_t(b0), uint8_t(b1)};
                    const Box4 box4 = Box4::of(box);
                    out.by_last[size_t(b1)].merge(box4);
                    out.by_first[size_t(b0)].merge(box4);
                    ++out.enter[size_t(b0)];
                    ++out.exit[size_t(b1)];
                }
            },
            storage);  // large nodes in parallel, like the other binning passes
    }

    /// The fine planes whose lower bound (up to rounding) of the binned cost
    /// is below `object_cost`, first to last. Left of plane b lie at least the
    /// boxes of the references wholly left of it (last bin < b: a triangle
    /// part touches every face of its reference's box) and, with a coarse
    /// pass whose planes are every (1 << shift)-th fine plane, the chopped
    /// parts of every coarse bin that ends at or before b (coarse bins
    /// [0, b >> shift)); the count is that of the references whose first bin
    /// is < b. Mirrored on the right. Up to rounding: a chopped part a few
    /// ulps wide may come out empty, a clipped reference box is rounded
    /// outward, and the union of a triangle's fine parts in a coarse bin is
    /// its coarse part only in exact arithmetic.
    static PlaneWindow candidate_planes(const LowerBoundBins& lb, const SpatialBins* coarse, int nb, int nc,
                                        int shift, double object_cost) {
        Box4 coarse_left[kSpatialGateBins + 1], coarse_right[kSpatialGateBins + 1];  // [c]: bins < c, >= c
        for (int c = 0; c < nc; ++c) {
            coarse_left[c + 1] = coarse_left[c];
            coarse_left[c + 1].merge(coarse->box[size_t(c)]);
        }
        for (int c = nc - 1; c >= 0; --c) {
            coarse_right[c] = coarse_right[c + 1];
            coarse_right[c].merge(coarse->box[size_t(c)]);
        }
        const int step = 1 << shift;
        PlaneWindow w{nb, 0};
        sweep_bins(nb, lb.by_last.data(), lb.enter.data(), lb.by_first.data(), lb.exit.data(),
                   [&](int b, const Box4& left, uint64_t nl, const Box4& right, uint64_t nr) {
                       Box4 l = left, r = right;
                       if (coarse) {
                           l.merge(coarse_left[b >> shift]);
                           r.merge(coarse_right[(b + step - 1) >> shift]);
                       }
                       if (l.half_area() * double(nl) + r.half_area() * double(nr) < object_cost) {
                           w.lo = std::min(w.lo, b);
                           w.hi = b;
                       }
                   });
        return w;
    }

    /// Adds one reference to the spatial bins: the triangle is chopped by the
    /// bin planes it spans (clipped against the triangle itself, intersected
    /// with the reference's box); enter/exit counts go to the first/last bin
    /// that really holds part of it.
    /// b0, b1: the reference's first and last bin (bin_of_lo, bin_of_hi).
    void bin_reference(const Ref& r, int a, const float* planes, int b0, int b1, SpatialBins& bins) const {
        if (b0 == b1) {
            bins.box[b0].merge(Box4::of(r.box));
            ++bins.enter[b0];
            ++bins.exit[b0];
            return;
        }
        const auto tri = scene_.triangle(r.tri);
        static thread_local std::vector<Aabb> parts;  // scratch, no task switch while in use
        if (parts.size() < size_t(kMaxBins)) parts.resize(kMaxBins);
        chop_triangle_estimate(tri, a, planes + b0, b1 - b0 + 1, r.box, parts.data());
        int first = -1, last = -1;
        for (int b = b0; b <= b1; ++b) {
            const Aabb& part = parts[b - b0];
            if (part.empty()) continue;
            bins.box[b].merge(Box4::of(part));
            if (first < 0) first = b;
            last = b;
        }
        if (first < 0) {  // cannot happen for a consistent reference; keep it whole
            bins.box[b0].merge(Box4::of(r.box));
            first = last = b0;
        }
        ++bins.enter[first];
        ++bins.exit[last];
    }

    /// Distributes references for a spatial split at s.plane, with
    /// reference unsplitting (Stich et al. 2009, section 4.4): a straddling
    /// reference is put wholly on one side when that is cheaper than
    /// duplicating it. Returns false (use the object split) when a side would
    /// be empty, a side would keep all references (allowed only
    /// kMaxNonShrinkingSpatial times per path), the duplicates exceed the budget, or the real cost is not
    /// below the object split's.
    bool spatial_partition(const RefList& refs, const Split& s, double object_cost,
                           uint64_t budget, bool allow_nonshrinking, RefList& left,
                           RefList& right) {
        const int a = s.axis;
        const float plane = s.plane;
        const float kInf = std::numeric_limits<float>::infinity();
        Aabb lbox = s.left, rbox = s.right;
        double nl = double(s.nl), nr = double(s.nr);
        left.clear();
        right.clear();
        left.reserve(s.nl);
        right.reserve(s.nr);
        for (const Ref& r : refs) {
            if (r.box.hi[a] <= plane) { left.push_back(r); continue; }
            if (r.box.lo[a] >= plane) { right.push_back(r); continue; }
            const auto tri = scene_.triangle(r.tri);
            const Aabb lpart = clip_triangle(tri, a, -kInf, plane, r.box);
            const Aabb rpart = clip_triangle(tri, a, plane, kInf, r.box);
            if (lpart.empty()) { right.push_back(Ref{rpart.empty() ? r.box : rpart, r.tri}); continue; }
            if (rpart.empty()) { left.push_back(Ref{lpart, r.tri}); continue; }
            const double c_split = lbox.half_area() * nl + rbox.half_area() * nr;
            Aabb lu = lbox; merge(lu, r.box);
            Aabb ru = rbox; merge(ru, r.box);
            const double c_left = lu.half_area() * nl + rbox.half_area() * (nr - 1);
            const double c_right = lbox.half_area() * (nl - 1) + ru.half_area() * nr;
            if (c_left < c_split && c_left <= c_right) {
                left.push_back(r);
                lbox = lu;
                nr -= 1;
            } else if (c_right < c_split) {
                right.push_back(r);
                rbox = ru;
                nl -= 1;
            } else {
                left.push_back(Ref{lpart, r.tri});
                right.push_back(Ref{rpart, r.tri});
            }
        }
        const size_t n = refs.size();
        const bool shrinks = left.size() < n && right.size() < n;
        if (left.empty() || right.empty() || (!shrinks && !allow_nonshrinking) ||
            left.size() + right.size() - n > budget)
            return false;
        Aabb la, ra;
        for (const Ref& r : left) merge(la, r.box);
        for (const Ref& r : right) merge(ra, r.box);
        const double cost = la.half_area() * double(left.size()) + ra.half_area() * double(right.size());
        return cost < object_cost;
    }

    const Scene& scene_;
    const SbvhConfig& config_;
    Progress* progress_;  ///< optional; written only, never read by the build
    double root_area_ = 0.0;
    std::atomic<uint64_t> spatial_splits_{0}, object_splits_{0};
};

size_t piece_nodes(const Piece& p) {
    return p.block.empty() ? 1 + piece_nodes(*p.child[0]) + piece_nodes(*p.child[1]) : p.block.size();
}

/// Canonical depth-first numbering (left subtree first), root = node 0: top
/// nodes in preorder, each block appended whole with its indices offset (a
/// block already is in that order) and released right after.
void flatten(Piece& p, std::vector<BinaryNode>& out) {
    if (!p.block.empty()) {
        const uint32_t offset = uint32_t(out.size());
        for (BinaryNode n : p.block) {
            if (!n.is_leaf()) {
                n.child[0] += offset;
                n.child[1] += offset;
            }
            out.push_back(n);
        }
        Block().swap(p.block);
        return;
    }
    const size_t index = out.size();
    out.push_back(p.node);
    out[index].child[0] = uint32_t(out.size());
    flatten(*p.child[0], out);
    out[index].child[1] = uint32_t(out.size());
    flatten(*p.child[1], out);
}

}  // namespace

Result build_sbvh(const Scene& scene, const SbvhConfig& config, BinaryBvh& out,
                Progress* progress) {
    out = BinaryBvh{};
    const size_t tris = scene.triangle_count();
    if (tris == 0) return Result::fail(Status::kInvalidArgument, 0, "build_sbvh: the scene has no triangles");
    if (tris >= kInvalidIndex / 4) {
        return Result::fail(Status::kInvalidArgument, 0, "build_sbvh: too many triangles for 32-bit node indices");
    }
    if (config.bins < 2 || config.bins > kMaxBins) {
        return Result::fail(Status::kInvalidArgument, 0, "build_sbvh: bins must be in 2..256");
    }
    if (!(config.max_reference_growth >= 0.0) || !(config.split_alpha >= 0.0f)) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "build_sbvh: split_alpha and max_reference_growth must be >= 0");
    }
    for (size_t i = 0; i < tris; ++i) {
        for (const uint32_t v : scene.indices[i]) {
            if (v >= scene.vertices.size()) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "build_sbvh: triangle " + std::to_string(i) + " has a vertex index out of range");
            }
            for (const float c : scene.vertices[v]) {
                if (!std::isfinite(c)) {
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "build_sbvh: triangle " + std::to_string(i) + " has a non-finite vertex");
                }
            }
        }
    }
    // Budget: the total number of references may grow by growth*tris, capped
    // so that node indices stay 32-bit.
    const double extra_d =
        std::min(config.max_reference_growth * double(tris), double(kInvalidIndex / 4) - double(tris));
    const uint64_t extra = uint64_t(std::max(0.0, extra_d));

    auto run = [&] {
        RefList refs(tris);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, tris, 16384), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                Aabb b;
                for (const Vec3& v : scene.triangle(i)) b.grow(v);
                refs[i] = Ref{b, uint32_t(i)};
            }
        });
        Builder builder(scene, config, progress);
        const std::unique_ptr<Piece> root = builder.build(refs, extra);
        out.nodes.clear();
        out.nodes.reserve(piece_nodes(*root));  // exact: no reallocation copy
        flatten(*root, out.nodes);
        out.spatial_splits = builder.spatial_splits();
        out.object_splits = builder.object_splits();
    };
    if (config.threads > 0) {
        tbb::task_arena arena(config.threads);
        arena.execute(run);
    } else {
        run();
    }
    uint64_t leaves = 0;
    for (const BinaryNode& n : out.nodes) leaves += n.is_leaf() ? 1 : 0;
    out.references = leaves;
    return Result::success();
}

Result build_boxes(const std::vector<Aabb>& boxes, const SbvhConfig& config, BinaryBvh& out) {
    out = BinaryBvh{};
    const size_t n = boxes.size();
    if (n == 0) return Result::fail(Status::kInvalidArgument, 0, "build_boxes: no boxes");
    if (n >= kInvalidIndex / 4) return Result::fail(Status::kInvalidArgument, 0, "build_boxes: too many boxes");
    for (size_t i = 0; i < n; ++i) {
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(boxes[i].lo[a]) || !std::isfinite(boxes[i].hi[a]) || !(boxes[i].lo[a] <= boxes[i].hi[a]))
                return Result::fail(Status::kInvalidArgument, 0,
                                    "build_boxes: box " + std::to_string(i) + " is empty or not finite");
        }
    }
    static const Scene kNoTriangles;  // never read: no reference budget, no spatial split
    auto run = [&] {
        RefList refs(n);
        for (size_t i = 0; i < n; ++i) refs[i] = Ref{boxes[i], uint32_t(i)};
        Builder builder(kNoTriangles, config, nullptr);
        const std::unique_ptr<Piece> root = builder.build_object_only(refs);
        out.nodes.reserve(piece_nodes(*root));
        flatten(*root, out.nodes);
        out.object_splits = builder.object_splits();
    };
    if (config.threads > 0) {
        tbb::task_arena arena(config.threads);
        arena.execute(run);
    } else {
        run();
    }
    out.references = n;
    return Result::success();
}

}  // namespace cwbvh::compiler
