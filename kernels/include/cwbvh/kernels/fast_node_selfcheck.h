// Device self-check of the fast node test (node_intersect_fast.h), of fp16.h and of the
// directed double-to-float conversions (format/float_round.h, axis_range.h's reach): on the
// GPU each must give the bits of its host emulation, which is what the warp model, the
// kernel emulation and the node test's contract test (tests/traverse) run. Generated
// cases: operand bit patterns for the half and directed-rounding operations (doubles of
// every exponent for the conversions), and
// (node, ray) pairs from a scene's own nodes with rays that take the fast test; for each
// pair also the per-ray set-up (make_node_ray + enable_fast_node_test: its NodeRay byte for
// byte on sm_80 and later) and the reference node test on the device. The reference test
// alone is not bit for bit: node_intersect.h lets nvcc contract its q * adj + orig into an
// fma (conservative either way), so a mask may differ where a box edge is within an ulp;
// more than 1 pair in 10,000 fails.
// cwbvh_gpu_check runs it on every GPU check (a mismatch fails the check), the gpu
// test area when a device is present. CUDA builds only (cwbvh_cuda).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"

namespace cwbvh {

struct FastNodeSelfCheck {
    bool ran = false;               ///< false: no device or a CUDA error (error says which)
    std::string error;
    uint64_t fp16_cases = 0, fp16_mismatches = 0;
    uint64_t node_pairs = 0, node_mismatches = 0;
    uint64_t node_pairs_hit = 0;    ///< pairs with a nonzero mask (the rays reach children)
    /// The first kReported differing cases, one line each, enough to rerun them on the
    /// host without a GPU: the operation, its operands' bits, the device's and the
    /// host's result bits; for a node pair the node's 80 bytes, the NodeRay's or the Ray's
    /// bytes, tmax and the scene's frame word in hex (node_mismatches counts the pairs where
    /// the fast mask or the set-up's NodeRay differ).
    static constexpr size_t kReported = 8;
    std::vector<std::string> differences;
    /// Pairs whose reference-test mask differs from the host's (see the file comment), and
    /// the first kReported of them, one line each.
    uint64_t reference_differences = 0;
    std::vector<std::string> reference_lines;
    bool reference_within_contraction() const { return reference_differences * 10000 <= node_pairs; }
};

/// Runs `fp16_cases` operation cases and `node_pairs` (node, ray) pairs drawn from
/// nodes[0, node_count) (deterministic in seed) on device 0 and compares every result with
/// the host emulation. node_count 0, or a scene the fast test cannot take: no pairs.
FastNodeSelfCheck run_fast_node_selfcheck(const CwbvhNode* nodes, size_t node_count, uint64_t seed = 1,
                                          size_t fp16_cases = size_t(1) << 18, size_t node_pairs = size_t(1) << 18);

}  // namespace cwbvh
