// CPU reference tracer (see cpu_trace.h).
#include "cwbvh/kernels/cpu_trace.h"

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/traverse_bvh2.h"
#include "cwbvh/kernels/traverse_two_level.h"

namespace cwbvh {
namespace {

uint32_t clamp_count(size_t n) { return n > 0xFFFFFFFFu ? 0xFFFFFFFFu : uint32_t(n); }

void accumulate(CpuTraceStats& s, TraceStatus status, const Hit& h, const TraceCounters& c) {
    ++s.rays;
    if (h.prim != kMissPrim) ++s.hits;
    if (status == TraceStatus::kInvalidRay) ++s.invalid_rays;
    if (status == TraceStatus::kStackOverflow) ++s.stack_overflows;
    if (status == TraceStatus::kBadIndex) ++s.bad_indices;
    s.nodes_visited += c.nodes;
    s.triangles_tested += c.triangles;
}

/// The traversal loops are compiled twice on x86-64: for CPUs with FMA (Haswell, Zen and
/// later: an fma is one instruction) and for the baseline (where __builtin_fmaf is a call
/// into libm), chosen once at load time (GCC function multiversioning, an ifunc). The
/// watertight test's shear (triangle_intersect.h shear_row) and the fast node test use
/// fmas so that the GPU's fused multiply-adds give the same bits on the host; the two
/// clones compute the same values (fmaf rounds once either way), the baseline one just
/// slower. `flatten` inlines everything the loops call into each clone (without it GCC
/// kept the BVH2 and two-level traversals and the triangle tests out of line, compiled
/// for the baseline).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define CWBVH_FMA_CLONES __attribute__((flatten, target_clones("fma", "default")))
#else
#define CWBVH_FMA_CLONES
#endif

// One chunk of rays with the test and mode fixed at compile time.
template <TriangleTest kTest, HitMode kMode, bool kBvh2, class NodeT>
CWBVH_FMA_CLONES CpuTraceStats trace_range(const NodeT* nodes, uint32_t node_count, const TriangleRecord* tris,
                          uint32_t tri_count, const Ray* rays, Hit* hits, size_t begin, size_t end,
                          const CpuTraceOptions& o) {
    CpuTraceStats s;
    for (size_t i = begin; i < end; ++i) {
        TraceCounters c{0, 0};
        TraceStatus st;
        if constexpr (kBvh2) {
            st = traverse_bvh2<kTest, kMode>(nodes, node_count, tris, tri_count, rays[i], hits[i], &c);
        } else {
            LocalStack<kCpuStackSize> stack;
            st = traverse_cwbvh<kTest, kMode>(nodes, node_count, tris, tri_count, rays[i], hits[i], stack, &c);
        }
        if (o.counters) o.counters[i] = c;
        if (o.statuses) o.statuses[i] = st;
        accumulate(s, st, hits[i], c);
    }
    return s;
}

template <bool kBvh2, class NodeT>
CpuTraceStats dispatch(const NodeT* nodes, uint32_t nc, const TriangleRecord* tris, uint32_t tc,
                       const Ray* rays, Hit* hits, size_t b, size_t e, const CpuTraceOptions& o) {
    const bool any = o.mode == HitMode::kAny;
    if (o.test == TriangleTest::kWatertight) {
        return any ? trace_range<TriangleTest::kWatertight, HitMode::kAny, kBvh2>(nodes, nc, tris, tc, rays, hits, b, e, o)
                   : trace_range<TriangleTest::kWatertight, HitMode::kClosest, kBvh2>(nodes, nc, tris, tc, rays, hits, b, e, o);
    }
    return any ? trace_range<TriangleTest::kFast, HitMode::kAny, kBvh2>(nodes, nc, tris, tc, rays, hits, b, e, o)
               : trace_range<TriangleTest::kFast, HitMode::kClosest, kBvh2>(nodes, nc, tris, tc, rays, hits, b, e, o);
}

/// Runs range(begin, end) -> CpuTraceStats over [0, ray_count) on o.threads threads.
template <class Range>
CpuTraceStats run_threads(size_t ray_count, const CpuTraceOptions& o, const Range& range) {
    const auto t0 = std::chrono::steady_clock::now();
    unsigned threads = o.threads ? o.threads : std::max(1u, std::thread::hardware_concurrency());
    // Chunks of at least 4096 rays, so tiny batches stay on the calling thread.
    const size_t max_threads = std::max<size_t>(1, ray_count / 4096);
    threads = unsigned(std::min<size_t>(threads, max_threads));
    CpuTraceStats total;
    if (threads <= 1) {
        total = range(size_t(0), ray_count);
    } else {
        // Interleaved blocks of 1024 rays balance incoherent workloads; each ray is
        // traced by exactly one thread, so results are thread-count independent.
        constexpr size_t kBlock = 1024;
        std::vector<CpuTraceStats> part(threads);
        std::vector<std::thread> pool;
        pool.reserve(threads);
        for (unsigned t = 0; t < threads; ++t) {
            pool.emplace_back([&, t] {
                for (size_t b = size_t(t) * kBlock; b < ray_count; b += size_t(threads) * kBlock) {
                    const CpuTraceStats s = range(b, std::min(ray_count, b + kBlock));
                    part[t] += s;
                }
            });
        }
        for (auto& th : pool) th.join();
        for (const auto& p : part) total += p;
    }
    total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return total;
}

template <bool kBvh2, class NodeT>
CpuTraceStats trace_all(const NodeT* nodes, size_t node_count, const TriangleRecord* tris,
                        size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                        const CpuTraceOptions& o) {
    const uint32_t nc = clamp_count(node_count), tc = clamp_count(tri_count);
    return run_threads(ray_count, o, [&](size_t b, size_t e) {
        return dispatch<kBvh2>(nodes, nc, tris, tc, rays, hits, b, e, o);
    });
}

template <TriangleTest kTest, HitMode kMode>
CWBVH_FMA_CLONES CpuTraceStats two_level_range(const TwoLevelScene& scene, const Ray* rays, Hit* hits, uint32_t* instances,
                              size_t begin, size_t end, const CpuTraceOptions& o) {
    CpuTraceStats s;
    for (size_t i = begin; i < end; ++i) {
        TraceCounters c{0, 0};
        LocalStack<kCpuStackSize> stack;
        uint32_t inst = kInvalidIndex;
        const TraceStatus st = traverse_two_level<kTest, kMode>(scene, rays[i], hits[i], inst, stack, &c);
        if (instances) instances[i] = inst;
        if (o.counters) o.counters[i] = c;
        if (o.statuses) o.statuses[i] = st;
        accumulate(s, st, hits[i], c);
    }
    return s;
}

}  // namespace

CpuTraceStats trace_cwbvh_cpu(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris,
                              size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                              const CpuTraceOptions& options) {
    return trace_all<false>(nodes, node_count, tris, tri_count, rays, hits, ray_count, options);
}

CpuTraceStats trace_bvh2_cpu(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris,
                             size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                             const CpuTraceOptions& options) {
    return trace_all<true>(nodes, node_count, tris, tri_count, rays, hits, ray_count, options);
}

CpuTraceStats trace_two_level_cpu(const TwoLevelScene& scene, const Ray* rays, Hit* hits, uint32_t* instances,
                                  size_t ray_count, const CpuTraceOptions& o) {
    return run_threads(ray_count, o, [&](size_t b, size_t e) {
        const bool any = o.mode == HitMode::kAny;
        if (o.test == TriangleTest::kWatertight) {
            return any ? two_level_range<TriangleTest::kWatertight, HitMode::kAny>(scene, rays, hits, instances, b, e, o)
                       : two_level_range<TriangleTest::kWatertight, HitMode::kClosest>(scene, rays, hits, instances, b, e, o);
        }
        return any ? two_level_range<TriangleTest::kFast, HitMode::kAny>(scene, rays, hits, instances, b, e, o)
                   : two_level_range<TriangleTest::kFast, HitMode::kClosest>(scene, rays, hits, instances, b, e, o);
    });
}

}  // namespace cwbvh
