// trace_on_gpu / gpu_available (cwbvh/kernels/gpu_trace.h) over DeviceScene + trace().
#include "cwbvh/kernels/gpu_trace.h"

#include <algorithm>
#include <chrono>
#include <vector>

#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/kernels/trace.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh {
namespace {

template <class T>
class DeviceBuffer {
public:
    explicit DeviceBuffer(size_t n) {
        if (n) CWBVH_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&p_), n * sizeof(T)));
    }
    ~DeviceBuffer() {
        if (p_) CWBVH_CUDA_WARN(cudaFree(p_));
    }
    DeviceBuffer(const DeviceBuffer&) = delete;
    DeviceBuffer& operator=(const DeviceBuffer&) = delete;
    T* get() const { return p_; }

private:
    T* p_ = nullptr;
};

double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

GpuStatus gpu_status(std::string& why) {
    int runtime = 0, driver = 0;
    cudaRuntimeGetVersion(&runtime);
    const cudaError_t de = cudaDriverGetVersion(&driver);
    int count = 0;
    const cudaError_t e = cudaGetDeviceCount(&count);
    if (e != cudaSuccess || count == 0) {
        GpuStatus status = GpuStatus::kUnusable;
        if (de != cudaSuccess || driver == 0) {
            // No libcuda: no NVIDIA driver is installed, so there is no device to use.
            why = "no CUDA driver loaded (libcuda not found)";
            status = GpuStatus::kNoDevice;
        } else if (e == cudaErrorNoDevice || (e == cudaSuccess && count == 0)) {
            why = "no CUDA device";
            status = GpuStatus::kNoDevice;
        } else if (e == cudaErrorInsufficientDriver || driver < runtime) {
            why = "CUDA driver too old: driver supports CUDA " + std::to_string(driver / 1000) + "." +
                  std::to_string(driver % 1000 / 10) + ", runtime is " + std::to_string(runtime / 1000) + "." +
                  std::to_string(runtime % 1000 / 10);
        } else {
            why = std::string("no usable CUDA device: ") + cudaGetErrorName(e) + " (" + cudaGetErrorString(e) + ")";
        }
        cudaGetLastError();  // clear the sticky-free error state
        return status;
    }
    try {
        KernelInfo info[8];
        kernel_info(info, 8);  // fails with cudaErrorNoKernelImageForDevice on an unsupported arch
    } catch (const CudaError& ce) {
        cudaDeviceProp prop{};
        cudaGetDeviceProperties(&prop, 0);
        why = std::string("no kernel image for device 0 (") + prop.name + ", sm_" + std::to_string(prop.major) +
              std::to_string(prop.minor) + "): rebuild with -DCMAKE_CUDA_ARCHITECTURES=native; " + ce.what();
        cudaGetLastError();
        return GpuStatus::kUnusable;
    }
    why.clear();
    return GpuStatus::kReady;
}

bool gpu_available(std::string& why) { return gpu_status(why) == GpuStatus::kReady; }

Expected<GpuTraceResult> trace_on_gpu(const File& file, const Ray* rays, Hit* hits, size_t n,
                                      const GpuTraceOptions& options) {
    return trace_on_gpu(file, rays, hits, nullptr, n, options);
}

Expected<GpuTraceResult> trace_on_gpu(const File& file, const Ray* rays, Hit* hits, uint32_t* instances, size_t n,
                                      const GpuTraceOptions& options) {
    GpuTraceResult r;
    r.rays = n;
    if (options.postpone_percent > 100)
        return Result::fail(Status::kInvalidArgument, 0, "CwbvhKernelOptions::postpone_percent above 100");
    std::string why;
    if (!gpu_available(why)) return Result::fail(Status::kDeviceError, 0, why);
    try {
        if (options.device >= 0) CWBVH_CUDA_CHECK(cudaSetDevice(options.device));
        int dev = 0;
        CWBVH_CUDA_CHECK(cudaGetDevice(&dev));
        cudaDeviceProp prop{};
        CWBVH_CUDA_CHECK(cudaGetDeviceProperties(&prop, dev));
        r.device_name = prop.name;

        UploadOptions up;
        up.bvh2 = options.kernel == GpuKernel::kBvh2;
        Expected<DeviceScene> scene = DeviceScene::upload(file, up);
        if (!scene.ok()) return scene.error();
        r.scene_upload_ms = scene->upload_stats().seconds * 1e3;
        const bool two_level = scene->has_two_level();
        if (two_level && options.kernel == GpuKernel::kBvh2) {
            return Result::fail(Status::kInvalidArgument, 0,
                                file.path() + ": a two-level scene: the BVH2 baseline kernel traces single-level files "
                                              "only (compile with cwbvhc --flatten)");
        }
        if (options.kernel == GpuKernel::kBvh2 && !scene->has_bvh2()) {
            return Result::fail(Status::kInvalidArgument, 0,
                                file.path() + ": no BVH2 section (compile with cwbvhc --keep-sbvh)");
        }
        r.node_bytes = options.kernel == GpuKernel::kBvh2 ? scene->bvh2_bytes() : scene->node_bytes();
        if (two_level) r.node_bytes += scene->top_level_bytes();
        r.triangle_bytes = scene->triangle_bytes();

        DeviceBuffer<Ray> d_rays(n);
        DeviceBuffer<Hit> d_hits(n);
        DeviceBuffer<uint32_t> d_instances(two_level && instances ? n : 0);
        auto t0 = std::chrono::steady_clock::now();
        if (n) CWBVH_CUDA_CHECK(cudaMemcpy(d_rays.get(), rays, n * sizeof(Ray), cudaMemcpyHostToDevice));
        r.rays_upload_ms = ms_since(t0);

        const Query q = options.any ? Query::kAny : Query::kClosest;
        TraceOptions to;
        to.test = options.test;
        static_cast<CwbvhKernelOptions&>(to) = options;
        DeviceTraceStats stats;
        std::vector<double> times;
        const int repeat = std::max(1, options.repeat);
        auto run = [&](float* ms, DeviceTraceStats* st) {
            to.kernel_ms = ms;
            to.stats = st;
            if (two_level) {
                trace_two_level(scene.value(), d_rays.get(), d_hits.get(), d_instances.get(), n, q, nullptr, to);
            } else if (options.kernel == GpuKernel::kBvh2) {
                trace_bvh2(scene.value(), d_rays.get(), d_hits.get(), n, q, nullptr, to);
            } else {
                trace(scene.value(), d_rays.get(), d_hits.get(), n, q, nullptr, to);
            }
        };
        // One untimed warm-up run (lazy module loading happens at the first launch), then
        // the timed runs: the kernel launches alone (TraceOptions::kernel_ms). The counters
        // come from one more run with the counting kernels, outside the timed ones.
        run(nullptr, nullptr);
        for (int i = 0; i < repeat; ++i) {
            float ms = 0;
            run(&ms, nullptr);
            times.push_back(ms);
        }
        run(nullptr, &stats);
        std::sort(times.begin(), times.end());
        r.kernel_ms = times[times.size() / 2];
        r.kernel_ms_min = times.front();
        r.mrays_per_s = r.kernel_ms > 0 ? double(n) / (r.kernel_ms * 1e3) : 0.0;

        t0 = std::chrono::steady_clock::now();
        if (n) CWBVH_CUDA_CHECK(cudaMemcpy(hits, d_hits.get(), n * sizeof(Hit), cudaMemcpyDeviceToHost));
        if (instances && n) {
            if (two_level) {
                CWBVH_CUDA_CHECK(
                    cudaMemcpy(instances, d_instances.get(), n * sizeof(uint32_t), cudaMemcpyDeviceToHost));
            } else {
                std::fill(instances, instances + n, kInvalidIndex);
            }
        }
        r.hits_download_ms = ms_since(t0);
        for (size_t i = 0; i < n; ++i) r.hits += hits[i].prim != kMissPrim;
        r.nodes_visited = stats.nodes_visited;
        r.triangles_tested = stats.triangles_tested;
        r.invalid_rays = stats.invalid_rays;
        r.stack_overflows = stats.stack_overflows;
        r.bad_indices = stats.bad_indices;
    } catch (const std::exception& e) {
        return Result::fail(Status::kDeviceError, 0, e.what());
    }
    return r;
}

}  // namespace cwbvh
