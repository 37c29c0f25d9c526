// Checked CUDA runtime calls. Every CUDA call in cwbvh goes through one of these
// macros so a failure names the file, line, expression and cudaGetErrorString.
//   CWBVH_CUDA_CHECK(expr): throws cwbvh::CudaError on failure (library code
//     catches it at the API boundary and turns it into an error string/status).
//   CWBVH_CUDA_WARN(expr):  for destructors: reports to stderr, never throws.
// Host-only header (needs the CUDA runtime API header, not nvcc).
#pragma once

#include <cuda_runtime_api.h>

#include <cstdio>
#include <stdexcept>
#include <string>

namespace cwbvh {

class CudaError : public std::runtime_error {
public:
    CudaError(cudaError_t code, const std::string& what) : std::runtime_error(what), code_(code) {}
    cudaError_t code() const { return code_; }

private:
    cudaError_t code_;
};

inline std::string cuda_error_text(cudaError_t e, const char* expr, const char* file, int line) {
    return std::string(file) + ":" + std::to_string(line) + ": " + expr + " failed: " + cudaGetErrorName(e) +
           " (" + cudaGetErrorString(e) + ")";
}

}  // namespace cwbvh

#define CWBVH_CUDA_CHECK(expr)                                                              \
    do {                                                                                    \
        const cudaError_t cwbvh_cuda_err_ = (expr);                                         \
        if (cwbvh_cuda_err_ != cudaSuccess)                                                 \
            throw ::cwbvh::CudaError(cwbvh_cuda_err_, ::cwbvh::cuda_error_text(             \
                                                          cwbvh_cuda_err_, #expr, __FILE__, __LINE__)); \
    } while (0)

#define CWBVH_CUDA_WARN(expr)                                                                  \
    do {                                                                                       \
        const cudaError_t cwbvh_cuda_err_ = (expr);                                            \
        if (cwbvh_cuda_err_ != cudaSuccess)                                                    \
            std::fprintf(stderr, "cwbvh: %s\n",                                                \
                         ::cwbvh::cuda_error_text(cwbvh_cuda_err_, #expr, __FILE__, __LINE__).c_str()); \
    } while (0)
