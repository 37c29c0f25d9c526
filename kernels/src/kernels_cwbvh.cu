// CWBVH kernel instantiations (loop: cwbvh/kernels/traverse_gpu.h).
#include "cwbvh/kernels/traverse_gpu.h"
#include "kernel_table.h"

namespace cwbvh {
namespace gpu {

template <TriangleTest kTest, HitMode kMode, bool kCount, bool kDefer>
__global__ void __launch_bounds__(kCwbvhBlockThreads, kCwbvhMinBlocksPerSm) cwbvh_trace_kernel(LaunchParams p) {
    // [warp][entry][lane]: see gpu_stack.h for the bank-conflict argument.
    __shared__ PackedEntry s_stack[kCwbvhWarpsPerBlock][kGpuSharedStackEntries][kWarpSize];
    trace_cwbvh_persistent<kTest, kMode, kCount, kDefer>(p, &s_stack[threadIdx.x / kWarpSize][0][0]);
}

#define CWBVH_KERNEL_ENTRY(name, test, mode, defer)                                                   \
    {name, cwbvh_trace_kernel<TriangleTest::test, HitMode::mode, false, defer>,                        \
     cwbvh_trace_kernel<TriangleTest::test, HitMode::mode, true, defer>, kCwbvhBlockThreads}

const KernelEntry* cwbvh_kernels() {
    static const KernelEntry k[kKernelsPerStructure] = {
        CWBVH_KERNEL_ENTRY("cwbvh_watertight_closest", kWatertight, kClosest, true),
        CWBVH_KERNEL_ENTRY("cwbvh_watertight_any", kWatertight, kAny, true),
        CWBVH_KERNEL_ENTRY("cwbvh_fast_closest", kFast, kClosest, true),
        CWBVH_KERNEL_ENTRY("cwbvh_fast_any", kFast, kAny, true),
    };
    return k;
}

const KernelEntry* cwbvh_whole_test_kernels() {
    static const KernelEntry k[kWholeTestKernels] = {
        CWBVH_KERNEL_ENTRY("cwbvh_watertight_closest_nodefer", kWatertight, kClosest, false),
        CWBVH_KERNEL_ENTRY("cwbvh_watertight_any_nodefer", kWatertight, kAny, false),
    };
    return k;
}

}  // namespace gpu
}  // namespace cwbvh
