// Statistics of a wide BVH: the SAH cost (spec formula) and children per node.
#include "cwbvh/compiler/collapse.h"

#include <algorithm>
#include <limits>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace cwbvh::compiler {

double sah_cost_wide(const WideBvh& wide, float c_node, float c_prim) {
    if (wide.nodes.empty()) return 0.0;
    const double root_area = wide.box(wide.nodes[0]).half_area();
    const double scale = root_area > 0.0 ? 1.0 / root_area : 1.0;
    // Sum in node order (deterministic); every node and leaf is a slot of
    // exactly one parent except the root. The terms of a block of nodes are
    // computed in parallel and added in that order: the same additions as one
    // serial loop, so the same bits for any thread count.
    constexpr size_t kBlock = size_t(1) << 15;
    constexpr size_t kTerms = 1 + kWidth;  // the node, then its leaf slots
    const size_t n = wide.nodes.size();
    std::vector<double> terms(std::min(n, kBlock) * kTerms);
    double sum = 0.0;
    for (size_t base = 0; base < n; base += kBlock) {
        const size_t count = std::min(kBlock, n - base);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 512), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t k = r.begin(); k != r.end(); ++k) {
                const WideNode& node = wide.nodes[base + k];
                double* t = &terms[k * kTerms];
                t[0] = double(c_node) * wide.box(node).half_area() * scale;
                for (int s = 0; s < kWidth; ++s) {
                    const WideChild& ch = node.slots[s];
                    t[1 + s] = ch.kind == WideChild::kLeaf ? double(c_prim) * ch.ref_count * wide.box(ch).half_area() * scale
                                                           : 0.0;
                }
            }
        });
        for (size_t k = 0; k < count; ++k) {
            const WideNode& node = wide.nodes[base + k];
            const double* t = &terms[k * kTerms];
            sum += t[0];
            for (int s = 0; s < kWidth; ++s)
                if (node.slots[s].kind == WideChild::kLeaf) sum += t[1 + s];
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
