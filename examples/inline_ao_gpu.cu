// inline_ao_gpu.h: the renderer's own kernel, calling the inline queries per pixel.
#include <cuda_runtime.h>

#include "inline_ao_gpu.h"

namespace cwbvh::example {
namespace {

__global__ void ao_kernel(SceneView scene, AoParams params, const Ray* rays, float* out, uint32_t n) {
    const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i < n) out[i] = ao_pixel(scene, params, rays[i], i);
}

bool check(cudaError_t e, const char* what, std::string& error) {
    if (e == cudaSuccess) return true;
    error = std::string(what) + ": " + cudaGetErrorString(e);
    return false;
}

}  // namespace

bool render_ao_gpu(const SceneView& scene, const AoParams& params, const std::vector<Ray>& rays,
                   std::vector<float>& ao, float& kernel_ms, std::string& error) {
    const uint32_t n = uint32_t(rays.size());
    Ray* d_rays = nullptr;
    float* d_out = nullptr;
    bool ok = check(cudaMalloc(&d_rays, n * sizeof(Ray)), "cudaMalloc", error) &&
              check(cudaMalloc(&d_out, n * sizeof(float)), "cudaMalloc", error) &&
              check(cudaMemcpy(d_rays, rays.data(), n * sizeof(Ray), cudaMemcpyHostToDevice), "cudaMemcpy", error);
    cudaEvent_t start = nullptr, stop = nullptr;
    ok = ok && check(cudaEventCreate(&start), "cudaEventCreate", error) &&
         check(cudaEventCreate(&stop), "cudaEventCreate", error);
    if (ok) {
        const unsigned threads = 128, blocks = (n + threads - 1) / threads;
        cudaEventRecord(start);
        ao_kernel<<<blocks, threads>>>(scene, params, d_rays, d_out, n);  // the view: device pointers, by value
        cudaEventRecord(stop);
        ok = check(cudaGetLastError(), "ao_kernel launch", error) &&
             check(cudaEventSynchronize(stop), "ao_kernel", error) &&
             check(cudaEventElapsedTime(&kernel_ms, start, stop), "cudaEventElapsedTime", error);
    }
    if (start) cudaEventDestroy(start);
    if (stop) cudaEventDestroy(stop);
    ao.resize(n);
    ok = ok && check(cudaMemcpy(ao.data(), d_out, n * sizeof(float), cudaMemcpyDeviceToHost), "cudaMemcpy", error);
    cudaFree(d_rays);
    cudaFree(d_out);
    return ok;
}

}  // namespace cwbvh::example
