// CPU reference tracer: runs the shared traversal (traverse.h, traverse_bvh2.h)
// unchanged over an array of rays, optionally on several std::threads.
// Results do not depend on the thread count. Library: cwbvh_cpu_trace.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/traverse_two_level.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

struct CpuTraceOptions {
    HitMode mode = HitMode::kClosest;
    TriangleTest test = TriangleTest::kWatertight;
    unsigned threads = 0;                ///< 0: std::thread::hardware_concurrency()
    TraceCounters* counters = nullptr;   ///< optional, one per ray
    TraceStatus* statuses = nullptr;     ///< optional, one per ray
};

struct CpuTraceStats {
    uint64_t rays = 0;
    uint64_t hits = 0;
    uint64_t invalid_rays = 0;     ///< not traceable, answered with a miss
    uint64_t stack_overflows = 0;  ///< tree deeper than the stack allows
    uint64_t bad_indices = 0;      ///< corrupt tree
    uint64_t nodes_visited = 0;
    uint64_t triangles_tested = 0;
    double seconds = 0.0;          ///< wall time of the trace

    /// Adds the counters of another part of the same trace (not the seconds).
    CpuTraceStats& operator+=(const CpuTraceStats& o) {
        rays += o.rays;
        hits += o.hits;
        invalid_rays += o.invalid_rays;
        stack_overflows += o.stack_overflows;
        bad_indices += o.bad_indices;
        nodes_visited += o.nodes_visited;
        triangles_tested += o.triangles_tested;
        return *this;
    }
};

/// Trace rays[0..ray_count) against a CWBVH (nodes[0] is the root); hits must hold
/// ray_count records.
CpuTraceStats trace_cwbvh_cpu(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris,
                              size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                              const CpuTraceOptions& options = {});

/// Same over a binary BVH (the BVH2 section).
CpuTraceStats trace_bvh2_cpu(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris,
                             size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                             const CpuTraceOptions& options = {});

/// Same over a two-level scene (traverse_two_level.h); instances (optional, ray_count
/// entries) receives each hit's INST index (kInvalidIndex for a miss).
CpuTraceStats trace_two_level_cpu(const TwoLevelScene& scene, const Ray* rays, Hit* hits, uint32_t* instances,
                                  size_t ray_count, const CpuTraceOptions& options = {});

}  // namespace cwbvh
