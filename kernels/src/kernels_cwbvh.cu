// CWBVH kernel instantiations (loop: cwbvh/traverse_gpu.h).
#include "cwbvh/traverse_gpu.h"
#include "kernel_table.h"

namespace cwbvh {
namespace gpu {

template <TriangleTest kTest, HitMode kMode>
__global__ void __launch_bounds__(kCwbvhBlockThreads) cwbvh_trace_kernel(LaunchParams p) {
    // [warp][entry][lane]: see gpu_stack.h for the bank-conflict argument.
    __shared__ PackedEntry s_stack[kCwbvhWarpsPerBlock][kGpuSharedStackEntries][kWarpSize];
    trace_cwbvh_persistent<kTest, kMode>(p, &s_stack[threadIdx.x / kWarpSize][0][0]);
}

const KernelEntry* cwbvh_kernels() {
    static const KernelEntry k[kKernelsPerStructure] = {
        {"cwbvh_watertight_closest", cwbvh_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest>,
         cwbvh_trace_kernel<TriangleTest::kWatertight, HitMode::kClosest>, kCwbvhBlockThreads},
        {"cwbvh_watertight_any", cwbvh_trace_kernel<TriangleTest::kWatertight, HitMode::kAny>,
         cwbvh_trace_kernel<TriangleTest::kWatertight, HitMode::kAny>, kCwbvhBlockThreads},
        {"cwbvh_fast_closest", cwbvh_trace_kernel<TriangleTest::kFast, HitMode::kClosest>,
         cwbvh_trace_kernel<TriangleTest::kFast, HitMode::kClosest>, kCwbvhBlockThreads},
        {"cwbvh_fast_any", cwbvh_trace_kernel<TriangleTest::kFast, HitMode::kAny>,
         cwbvh_trace_kernel<TriangleTest::kFast, HitMode::kAny>, kCwbvhBlockThreads},
    };
    return k;
}

}  // namespace gpu
}  // namespace cwbvh
