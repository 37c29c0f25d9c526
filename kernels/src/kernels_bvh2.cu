// BVH2 baseline kernel instantiations (loop: cwbvh/traverse_gpu_bvh2.h).
#include "cwbvh/traverse_gpu_bvh2.h"
#include "kernel_table.h"

namespace cwbvh {
namespace gpu {

template <TriangleTest kTest, HitMode kMode>
__global__ void __launch_bounds__(kBvh2BlockThreads) bvh2_trace_kernel(LaunchParams p) {
    trace_bvh2_persistent<kTest, kMode>(p);
}

const KernelEntry* bvh2_kernels() {
    static const KernelEntry k[kKernelsPerStructure] = {
        {"bvh2_watertight_closest", bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest>,
         bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest>, kBvh2BlockThreads},
        {"bvh2_watertight_any", bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kAny>,
         bvh2_trace_kernel<TriangleTest::kWatertight, HitMode::kAny>, kBvh2BlockThreads},
        {"bvh2_fast_closest", bvh2_trace_kernel<TriangleTest::kFast, HitMode::kClosest>,
         bvh2_trace_kernel<TriangleTest::kFast, HitMode::kClosest>, kBvh2BlockThreads},
        {"bvh2_fast_any", bvh2_trace_kernel<TriangleTest::kFast, HitMode::kAny>,
         bvh2_trace_kernel<TriangleTest::kFast, HitMode::kAny>, kBvh2BlockThreads},
    };
    return k;
}

}  // namespace gpu
}  // namespace cwbvh
