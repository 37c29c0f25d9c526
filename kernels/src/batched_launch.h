// The launch driver every trace kernel shares (trace.cu, trace_two_level.cu): the ray
// range cut into launches of at most kMaxRaysPerLaunch, one zeroed WorkArea per launch,
// events around the launches alone (TraceOptions::kernel_ms), the statistics summed
// over the work areas (TraceOptions::stats), everything freed on every path.
#pragma once

#include <cuda_runtime.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/kernels/gpu_common.h"
#include "cwbvh/kernels/trace.h"

namespace cwbvh::gpu {

/// Grid size of one launch: the persistent grid, or options.blocks, but never more
/// blocks than the launch has rays for.
inline uint32_t launch_blocks(uint32_t persistent, const TraceOptions& options, uint32_t count,
                              uint32_t block_threads) {
    const uint32_t blocks = options.blocks ? options.blocks : persistent;
    return std::min(blocks, (count + block_threads - 1) / block_threads);
}

/// Runs launch_one(first, count, work) for each batch of the n rays on `stream`;
/// launch_one launches its kernel and returns the number of blocks it used.
template <class LaunchOne>
void run_batched(size_t n, cudaStream_t stream, const TraceOptions& options, uint32_t block_threads,
                 LaunchOne launch_one) {
    WorkArea* work = nullptr;
    const size_t batches = n == 0 ? 0 : size_t((n - 1) / kMaxRaysPerLaunch + 1);
    const size_t work_bytes = sizeof(WorkArea) * std::max<size_t>(batches, 1);
    CWBVH_CUDA_CHECK(cudaMallocAsync(reinterpret_cast<void**>(&work), work_bytes, stream));
    uint32_t blocks_used = 0;
    cudaEvent_t ev[2] = {nullptr, nullptr};
    auto destroy_events = [&]() {
        for (cudaEvent_t& e : ev) {
            if (e) CWBVH_CUDA_WARN(cudaEventDestroy(e));
            e = nullptr;
        }
    };
    try {
        CWBVH_CUDA_CHECK(cudaMemsetAsync(work, 0, work_bytes, stream));
        if (options.kernel_ms) {
            CWBVH_CUDA_CHECK(cudaEventCreate(&ev[0]));
            CWBVH_CUDA_CHECK(cudaEventCreate(&ev[1]));
            CWBVH_CUDA_CHECK(cudaEventRecord(ev[0], stream));
        }
        for (size_t b = 0; b < batches; ++b) {
            const size_t first = b * kMaxRaysPerLaunch;
            const uint32_t count = uint32_t(std::min<uint64_t>(n - first, kMaxRaysPerLaunch));
            blocks_used = std::max(blocks_used, launch_one(first, count, work + b));
            CWBVH_CUDA_CHECK(cudaGetLastError());
        }
        if (options.kernel_ms) {
            CWBVH_CUDA_CHECK(cudaEventRecord(ev[1], stream));
            CWBVH_CUDA_CHECK(cudaEventSynchronize(ev[1]));
            CWBVH_CUDA_CHECK(cudaEventElapsedTime(options.kernel_ms, ev[0], ev[1]));
            destroy_events();
        }
        if (options.stats) {
            DeviceTraceStats s;
            s.rays = n;
            s.blocks = blocks_used;
            s.threads_per_block = block_threads;
            for (size_t b = 0; b < std::max<size_t>(batches, 1); ++b) {
                WorkArea w{};
                CWBVH_CUDA_CHECK(cudaMemcpyAsync(&w, work + b, sizeof(w), cudaMemcpyDeviceToHost, stream));
                CWBVH_CUDA_CHECK(cudaStreamSynchronize(stream));
                s.nodes_visited += w.nodes;
                s.triangles_tested += w.triangles;
                s.invalid_rays += w.invalid;
                s.stack_overflows += w.overflows;
                s.bad_indices += w.bad_indices;
            }
            *options.stats = s;
        }
    } catch (...) {
        destroy_events();
        CWBVH_CUDA_WARN(cudaFreeAsync(work, stream));
        throw;
    }
    CWBVH_CUDA_CHECK(cudaFreeAsync(work, stream));
}

}  // namespace cwbvh::gpu
