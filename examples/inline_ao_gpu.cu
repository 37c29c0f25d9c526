// inline_ao_gpu.h: the renderer's own kernel, calling the inline queries per pixel.
#include <cuda_runtime.h>

#include "inline_ao_gpu.h"

namespace cwbvh::example {
namespace {

__global__ void ao_kernel(SceneView scene, AoCamera camera, float* out) {
    const int x = int(blockIdx.x * blockDim.x + threadIdx.x), y = int(blockIdx.y * blockDim.y + threadIdx.y);
    if (x >= camera.width || y >= camera.height) return;
    out[size_t(y) * size_t(camera.width) + size_t(x)] = ao_pixel(scene, camera, x, y);
}

bool check(cudaError_t e, const char* what, std::string& error) {
    if (e == cudaSuccess) return true;
    error = std::string(what) + ": " + cudaGetErrorString(e);
    return false;
}

}  // namespace

bool render_ao_gpu(const SceneView& scene, const AoCamera& camera, std::vector<float>& ao, float& kernel_ms,
                   std::string& error) {
    const size_t n = size_t(camera.width) * size_t(camera.height);
    float* d_out = nullptr;
    if (!check(cudaMalloc(&d_out, n * sizeof(float)), "cudaMalloc", error)) return false;
    cudaEvent_t start, stop;
    bool ok = check(cudaEventCreate(&start), "cudaEventCreate", error) &&
              check(cudaEventCreate(&stop), "cudaEventCreate", error);
    if (ok) {
        const dim3 block(16, 8), grid((camera.width + 15) / 16, (camera.height + 7) / 8);
        cudaEventRecord(start);
        ao_kernel<<<grid, block>>>(scene, camera, d_out);  // the view: device pointers, by value
        cudaEventRecord(stop);
        ok = check(cudaGetLastError(), "ao_kernel launch", error) &&
             check(cudaEventSynchronize(stop), "ao_kernel", error) &&
             check(cudaEventElapsedTime(&kernel_ms, start, stop), "cudaEventElapsedTime", error);
        cudaEventDestroy(start);
        cudaEventDestroy(stop);
    }
    ao.resize(n);
    ok = ok && check(cudaMemcpy(ao.data(), d_out, n * sizeof(float), cudaMemcpyDeviceToHost), "cudaMemcpy", error);
    cudaFree(d_out);
    return ok;
}

}  // namespace cwbvh::example
