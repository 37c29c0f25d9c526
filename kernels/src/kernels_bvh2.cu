// BVH2 baseline kernel instantiations (warp loop: cwbvh/kernels/traverse_gpu_bvh2.h; lane
// steps: cwbvh/kernels/bvh2_lane.h): Aila, Karras, Laine 2012 kepler_dynamic_fetch.
#include "cwbvh/kernels/traverse_gpu_bvh2.h"
#include "kernel_table.h"

namespace cwbvh {
namespace gpu {

/// kCount: the stats variant (counts node and triangle steps into WorkArea).
template <TriangleTest kTest, HitMode kMode, bool kCount>
__global__ void __launch_bounds__(kBvh2BlockThreads) bvh2_trace_kernel(LaunchParams p) {
    trace_bvh2_persistent<kTest, kMode, kCount>(p);
}

const KernelEntry* bvh2_kernels() {
    static const KernelEntry k[kKernelsPerStructure] = {
        {"bvh2_watertight_closest", bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest, false>,
         bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest, true>, kBvh2BlockThreads},
        {"bvh2_watertight_any", bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kAny, false>,
         bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kAny, true>, kBvh2BlockThreads},
        {"bvh2_fast_closest", bvh2_trace_kernel<TriangleTest::kFast, HitMode::kClosest, false>,
         bvh2_trace_kernel<TriangleTest::kFast, HitMode::kClosest, true>, kBvh2BlockThreads},
        {"bvh2_fast_any", bvh2_trace_kernel<TriangleTest::kFast, HitMode::kAny, false>,
         bvh2_trace_kernel<TriangleTest::kFast, HitMode::kAny, true>, kBvh2BlockThreads},
    };
    return k;
}

}  // namespace gpu
}  // namespace cwbvh
