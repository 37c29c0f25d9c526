// Pieces of the compiler's parallel checks (check_binary, check_wide, the
// encoder, the PMAP check): results depend on the data only, never on the
// schedule, so the lowest failing index reports as in a serial pass.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <cstdint>

#include <tbb/blocked_range.h>
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

}  // namespace cwbvh::compiler
