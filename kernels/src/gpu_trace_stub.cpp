// gpu_trace.h in a build without CUDA: reports why there is no GPU path.
#include "cwbvh/kernels/gpu_trace.h"

namespace cwbvh {

GpuStatus gpu_status(std::string& why) {
    why = "cwbvh was built without CUDA (no nvcc at configure time, or CWBVH_CUDA=OFF)";
    return GpuStatus::kNoCuda;
}

bool gpu_available(std::string& why) { return gpu_status(why) == GpuStatus::kReady; }

Expected<GpuTraceResult> trace_on_gpu(const File&, const Ray*, Hit*, size_t, const GpuTraceOptions&) {
    std::string why;
    gpu_available(why);
    return Result::fail(Status::kDeviceError, 0, why);
}

Expected<GpuTraceResult> trace_on_gpu(const File&, const Ray*, Hit*, uint32_t*, size_t, const GpuTraceOptions&) {
    std::string why;
    gpu_available(why);
    return Result::fail(Status::kDeviceError, 0, why);
}

}  // namespace cwbvh
