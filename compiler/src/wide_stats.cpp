// Statistics of a wide BVH: the SAH cost (spec formula) and children per node.
#include "cwbvh/compiler/collapse.h"

namespace cwbvh::compiler {

double sah_cost_wide(const WideBvh& wide, float c_node, float c_prim) {
    if (wide.nodes.empty()) return 0.0;
    const double root_area = wide.nodes[0].box.half_area();
    const double scale = root_area > 0.0 ? 1.0 / root_area : 1.0;
    // Sum in node order (deterministic); every node and leaf is a slot of
    // exactly one parent except the root.
    double sum = 0.0;
    for (const WideNode& node : wide.nodes) {
        sum += double(c_node) * node.box.half_area() * scale;
        for (const WideChild& ch : node.slots) {
            if (ch.kind == WideChild::kLeaf) sum += double(c_prim) * ch.ref_count * ch.box.half_area() * scale;
        }
    }
    return sum;
}

double wide_avg_children(const WideBvh& wide) {
    if (wide.nodes.empty()) return 0.0;
    uint64_t children = 0;
    for (const WideNode& node : wide.nodes) children += uint64_t(node.child_count());
    return double(children) / double(wide.nodes.size());
}

}  // namespace cwbvh::compiler
