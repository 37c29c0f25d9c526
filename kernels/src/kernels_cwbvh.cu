// CWBVH kernel instantiations (loop: cwbvh/kernels/traverse_gpu.h).
#include "cwbvh/kernels/traverse_gpu.h"
#include "kernel_table.h"

namespace cwbvh {
namespace gpu {

template <TriangleTest kTest, HitMode kMode, bool kCount>
__global__ void __launch_bounds__(kCwbvhBlockThreads, kCwbvhMinBlocksPerSm) cwbvh_trace_kernel(LaunchParams p) {
    // [warp][entry][lane]: see gpu_stack.h for the bank-conflict argument.
    __shared__ PackedEntry s_stack[kCwbvhWarpsPerBlock][kGpuSharedStackEntries][kWarpSize];
    trace_cwbvh_persistent<kTest, kMode, kCount>(p, &s_stack[threadIdx.x / kWarpSize][0][0]);
}

#define CWBVH_KERNEL_ENTRY(name, test, mode)                                                          \
    {name, cwbvh_trace_kernel<TriangleTest::test, HitMode::mode, false>,                               \
     cwbvh_trace_kernel<TriangleTest::test, HitMode::mode, true>, kCwbvhBlockThreads}

const KernelEntry* cwbvh_kernels() {
    static const KernelEntry k[kKernelsPerStructure] = {
        CWBVH_KERNEL_ENTRY("cwbvh_watertight_closest", kWatertight, kClosest),
        CWBVH_KERNEL_ENTRY("cwbvh_watertight_any", kWatertight, kAny),
        CWBVH_KERNEL_ENTRY("cwbvh_fast_closest", kFast, kClosest),
        CWBVH_KERNEL_ENTRY("cwbvh_fast_any", kFast, kAny),
    };
    return k;
}

}  // namespace gpu
}  // namespace cwbvh
