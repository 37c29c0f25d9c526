// Statistics of a wide BVH: the SAH cost (spec formula) and children per node.
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/parallel_exact.h"

namespace cwbvh::compiler {

double sah_cost_wide(const WideBvh& wide, float c_node, float c_prim) {
    if (wide.nodes.empty()) return 0.0;
    const double root_area = wide.box(wide.nodes[0]).half_area();
    const double scale = root_area > 0.0 ? 1.0 / root_area : 1.0;
    // Sum in node order (deterministic for any thread count: ordered_sum);
    // every node and leaf is a slot of exactly one parent except the root.
    // Slots that are not leaves add +0.0, which leaves the (non-negative)
    // sum's bits as they are.
    const double sum = ordered_sum(wide.nodes.size(), 1 + kWidth, [&](size_t i, double* t) {
        const WideNode& node = wide.nodes[i];
        t[0] = double(c_node) * wide.box(node).half_area() * scale;
        for (int s = 0; s < kWidth; ++s) {
            const WideChild& ch = node.slots[s];
            t[1 + s] = ch.kind == WideChild::kLeaf ? double(c_prim) * ch.ref_count * wide.box(ch).half_area() * scale
                                                   : 0.0;
        }
    });
    return sum;
}

double wide_avg_children(const WideBvh& wide) {
    if (wide.nodes.empty()) return 0.0;
    uint64_t children = 0;
    for (const WideNode& node : wide.nodes) children += uint64_t(node.child_count());
    return double(children) / double(wide.nodes.size());
}

}  // namespace cwbvh::compiler
