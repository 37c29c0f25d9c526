#include "cwbvh/compiler/sah_report.h"

#include <vector>

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
    std::vector<double> area(nodes.size(), 0.0);
    area[0] = root_area;
    double internal = 0.0, leaf = 0.0, sum = 0.0;
    for (size_t i = 0; i < nodes.size(); ++i) {
        const CwbvhNode& n = nodes[i];
        internal += area[i];
        sum += area[i];
        for (int s = 0; s < kWidth; ++s) {
            const uint8_t meta = n.meta[s];
            if (meta_is_empty(meta)) continue;
            const double a = decode_child_box(n, s).half_area();
            if (meta_is_internal(meta)) {
                const uint32_t child = internal_child_index(n, s);
                if (child < nodes.size()) area[child] = a;
            } else {
                leaf += a * double(meta_leaf_count(meta));
                sum += a * double(meta_leaf_count(meta));
            }
        }
    }
    return {internal / root_area, leaf / root_area, sum / root_area};
}

}  // namespace cwbvh::compiler
