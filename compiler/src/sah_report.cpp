#include "cwbvh/compiler/sah_report.h"

#include <algorithm>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/quantize.h"
#include "cwbvh/format/node_decode.h"

namespace cwbvh::compiler {

double report_sah_binary(const BinaryBvh& bvh) { return sah_cost_binary(bvh, 1.0f, 1.0f); }

double report_sah_wide(std::span<const CwbvhNode> nodes, const Aabb& root) {
    return report_sah_wide_parts(nodes, root).total;
}

WideSahParts report_sah_wide_parts(std::span<const CwbvhNode> nodes, const Aabb& root) {
    const double root_area = root.half_area();
    if (nodes.empty() || !(root_area > 0.0)) return {};
    // area[i]: the box node i is entered through (its parent's decoded slot box).
    // The slot areas of a block of nodes are decoded in parallel; the sums
    // and area[] are then walked in node order exactly as one serial loop
    // (same additions, same bits, and the last parent wins on a malformed tree).
    std::vector<double> area(nodes.size(), 0.0);
    area[0] = root_area;
    double internal = 0.0, leaf = 0.0, sum = 0.0;
    constexpr size_t kBlock = size_t(1) << 15;
    std::vector<double> slot_area(std::min(nodes.size(), kBlock) * kWidth);
    for (size_t base = 0; base < nodes.size(); base += kBlock) {
        const size_t count = std::min(kBlock, nodes.size() - base);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 512), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t k = r.begin(); k != r.end(); ++k) {
                const CwbvhNode& n = nodes[base + k];
                for (int s = 0; s < kWidth; ++s)
                    slot_area[k * kWidth + size_t(s)] =
                        meta_is_empty(n.meta[s]) ? 0.0 : decode_child_box(n, s).half_area();
            }
        });
        for (size_t k = 0; k < count; ++k) {
            const size_t i = base + k;
            const CwbvhNode& n = nodes[i];
            internal += area[i];
            sum += area[i];
            for (int s = 0; s < kWidth; ++s) {
                const uint8_t meta = n.meta[s];
                if (meta_is_empty(meta)) continue;
                const double a = slot_area[k * kWidth + size_t(s)];
                if (meta_is_internal(meta)) {
                    const uint32_t child = internal_child_index(n, s);
                    if (child < nodes.size()) area[child] = a;
                } else {
                    leaf += a * double(meta_leaf_count(meta));
                    sum += a * double(meta_leaf_count(meta));
                }
            }
        }
    }
    return {internal / root_area, leaf / root_area, sum / root_area};
}

}  // namespace cwbvh::compiler
