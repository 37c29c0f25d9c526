// The OptiX 9.0 peer of the benchmark (bench/optix/README.md): traces the same device
// Ray records as the CWBVH and BVH2 kernels (cwbvh/kernels/trace.h) through an OptiX
// geometry acceleration structure (GAS) over the same triangles, and writes the same
// Hit records, so tools/gpu_check compares all three with one function against the CPU
// reference. No OptiX type appears here: users need only the CUDA runtime header.
//
// The GAS: one triangle build input over the stored triangles of a .cwbvh file (TRIS
// section: primitive i of the GAS = stored triangle id i, so Hit::prim means the same
// as the kernels'), OPTIX_BUILD_FLAG_PREFER_FAST_TRACE | ALLOW_COMPACTION, then
// compacted; geometry flag DISABLE_ANYHIT (opaque: no any-hit program runs).
// Errors (OptiX or CUDA) throw std::runtime_error (CudaError for CUDA calls).
#pragma once

#include <cuda_runtime_api.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray.h"

namespace cwbvh {

/// What a GAS build cost (CUDA events around optixAccelBuild, and around the
/// compaction copy; the size query and allocations are outside both).
struct OptixGasInfo {
    uint64_t triangles = 0;          ///< GAS primitives (stored triangles)
    uint64_t gas_bytes = 0;          ///< compacted GAS size
    uint64_t uncompacted_bytes = 0;  ///< GAS size before compaction
    uint64_t temp_bytes = 0;         ///< build scratch
    double build_ms = 0;             ///< optixAccelBuild
    double compact_ms = 0;           ///< optixAccelCompact
};

class OptixPeer {
public:
    /// Loads libnvoptix (optix_stubs.h: at run time, so this links without it), creates
    /// a context on the current CUDA device and the pipeline. Returns nullptr and sets
    /// `why` (one line) when OptiX cannot run here: no libnvoptix, driver too old for
    /// the headers' ABI, or no device.
    static std::unique_ptr<OptixPeer> create(std::string& why);
    ~OptixPeer();
    OptixPeer(const OptixPeer&) = delete;
    OptixPeer& operator=(const OptixPeer&) = delete;

    /// Builds (or rebuilds) the GAS over `n` triangle records (host memory): GAS
    /// primitive p = the record with prim == p; ids never stored become degenerate
    /// (zero-area) triangles that OptiX never reports.
    OptixGasInfo build(const TriangleRecord* tris, size_t n);

    /// Traces n device rays into n device hits on `stream` (closest or any hit), then
    /// synchronises. launch_ms, when set: CUDA events around optixLaunch alone (the
    /// launch-parameter upload is before the first event), as TraceOptions::kernel_ms.
    void trace(const Ray* d_rays, Hit* d_hits, size_t n, bool any, float* launch_ms = nullptr,
               cudaStream_t stream = nullptr);

    /// "OptiX 9.0.0 (ABI N)" for reports.
    static std::string version();

private:
    struct Impl;
    explicit OptixPeer(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace cwbvh
