// Internal: the kernel instantiations of each structure, as host-side entries that
// trace.cu launches (kernels_cwbvh.cu, kernels_bvh2.cu define them). Host code only:
// launching a __global__ function from another translation unit needs just its
// host stub, so no relocatable device code is involved.
#pragma once

#include <cuda_runtime.h>

#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {
namespace gpu {

struct LaunchParams;

using KernelFn = void (*)(LaunchParams);

struct KernelEntry {
    const char* name;
    KernelFn fn;         ///< production variant (no work counters)
    KernelFn counting;   ///< same traversal, also counting nodes/triangles (stats runs)
    int block_threads;
};

/// Index within a structure: test * 2 + query (watertight/fast x closest/any).
inline constexpr int kKernelsPerStructure = 4;
inline constexpr int kernel_slot(TriangleTest test, HitMode mode) {
    return (test == TriangleTest::kFast ? 2 : 0) + (mode == HitMode::kAny ? 1 : 0);
}

const KernelEntry* cwbvh_kernels();  ///< kKernelsPerStructure entries
/// The watertight CWBVH kernels without deferred hit distances (TraceOptions::defer_hits
/// = false): closest, any.
inline constexpr int kWholeTestKernels = 2;
const KernelEntry* cwbvh_whole_test_kernels();
const KernelEntry* bvh2_kernels();   ///< kKernelsPerStructure entries

}  // namespace gpu
}  // namespace cwbvh
