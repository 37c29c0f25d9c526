// Parallel loops of the compiler whose results depend on the data only, never
// on the schedule: the checks (check_binary, check_wide, the encoder,
// verify_encoded, the PMAP check) report the lowest failing index as a serial
// pass would, and sums come out with the bits of a serial loop.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>

#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

namespace cwbvh::compiler {

/// The lowest i in [0, n) with failed(i), or n when there is none. failed is
/// called exactly once for every i (it may also do the work the check is
/// part of), from any thread, in any order.
template <class Failed>
size_t lowest_failing(size_t n, size_t grain, Failed&& failed) {
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, n, grain), n,
        [&](const tbb::blocked_range<size_t>& r, size_t lowest) {
            for (size_t i = r.begin(); i != r.end(); ++i)
                if (failed(i) && i < lowest) lowest = i;
            return lowest;
        },
        [](size_t a, size_t b) { return std::min(a, b); });
}

/// Counts one more parent of a node in its marks byte: bit 0 once there is
/// one, bit 1 once there is a second (concurrent calls on one byte allowed).
/// A node with exactly one parent ends with marks == 1.
inline void mark_parent(uint8_t& marks) {
    std::atomic_ref<uint8_t> m(marks);
    if (m.fetch_or(1, std::memory_order_relaxed) & 1) m.fetch_or(2, std::memory_order_relaxed);
}

/// The sum of n * per terms in index order, bit for bit one serial loop's:
/// fill(i, t) writes item i's `per` terms to t[0..per), in parallel by blocks;
/// the terms are then added in order (i, then t) on this thread.
template <class Fill>
double ordered_sum(size_t n, size_t per, Fill&& fill) {
    constexpr size_t kBlock = size_t(1) << 15;
    std::vector<double> terms(std::min(n, kBlock) * per);
    double sum = 0.0;
    for (size_t base = 0; base < n; base += kBlock) {
        const size_t count = std::min(kBlock, n - base);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 512), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t k = r.begin(); k != r.end(); ++k) fill(base + k, &terms[k * per]);
        });
        for (size_t k = 0; k < count * per; ++k) sum += terms[k];
    }
    return sum;
}

}  // namespace cwbvh::compiler
