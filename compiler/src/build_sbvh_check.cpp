// SAH cost of a binary BVH (spec formula) and the structural/coverage check
// of a BinaryBvh against its scene, used by tests and by `cwbvhc --check`.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/parallel_exact.h"

namespace cwbvh::compiler {

double sah_cost_binary(const BinaryBvh& bvh, float c_node, float c_prim) {
    if (bvh.nodes.empty()) return 0.0;
    const double root = bvh.nodes[0].box.half_area();  // ratios: half areas suffice
    if (!(root > 0.0)) return 0.0;
    // Summed in node order (fixed), so the value is reproducible for any
    // thread count (terms in parallel, added in order: ordered_sum).
    const double sum = ordered_sum(bvh.nodes.size(), 1, [&](size_t i, double* t) {
        const BinaryNode& node = bvh.nodes[i];
        t[0] = (node.is_leaf() ? double(c_prim) : double(c_node)) * node.box.half_area() / root;
    });
    return sum;
}

namespace {
bool contains(const Aabb& outer, const Aabb& inner) {
    for (int j = 0; j < 3; ++j) {
        if (!(outer.lo[j] <= inner.lo[j] && inner.hi[j] <= outer.hi[j])) return false;
    }
    return true;
}
std::string box_str(const Aabb& b) {
    char buf[256];
    std::snprintf(buf, sizeof buf, "[%.9g %.9g %.9g]-[%.9g %.9g %.9g]", b.lo[0], b.lo[1], b.lo[2],
                  b.hi[0], b.hi[1], b.hi[2]);
    return buf;
}
}  // namespace

Result validate_binary_bvh(const Scene& scene, const BinaryBvh& bvh, int samples,
                         uint64_t seed) {
    const size_t tris = scene.triangle_count();
    const auto& nodes = bvh.nodes;
    if (nodes.empty()) return Result::fail(Status::kInternal, 0, "no nodes");
    // Depth-first layout, left first, root 0: visiting from the root must
    // produce indices 0, 1, 2, ... in order.
    std::vector<std::vector<uint32_t>> leaves_of(tris);
    std::vector<uint32_t> stack{0};
    uint32_t expect = 0;
    uint64_t leaves = 0;
    while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        if (i != expect) {
            return Result::fail(
                Status::kInternal, 0,
                "node " + std::to_string(i) + " is not in depth-first order (expected " + std::to_string(expect) + ")");
        }
        ++expect;
        const BinaryNode& n = nodes[i];
        if (n.box.empty()) return Result::fail(Status::kInternal, 0, "node " + std::to_string(i) + " has an empty box");
        if (n.is_leaf()) {
            if (n.prim() >= tris) {
                return Result::fail(Status::kInternal, 0,
                                    "leaf " + std::to_string(i) + " has triangle id out of range");
            }
            Aabb tb;
            for (const Vec3& v : scene.triangle(n.prim())) tb.grow(v);
            Aabb meet;
            for (int j = 0; j < 3; ++j) {
                meet.lo[j] = std::max(tb.lo[j], n.box.lo[j]);
                meet.hi[j] = std::min(tb.hi[j], n.box.hi[j]);
            }
            if (meet.empty()) {
                return Result::fail(Status::kInternal, 0,
                                    "leaf " + std::to_string(i) + " box " + box_str(n.box) + " misses triangle " +
                                        std::to_string(n.prim()) + " box " + box_str(tb));
            }
            leaves_of[n.prim()].push_back(i);
            ++leaves;
            continue;
        }
        for (int c = 0; c < 2; ++c) {
            const uint32_t ch = n.child[c];
            if (ch >= nodes.size() || ch <= i) {
                return Result::fail(Status::kInternal, 0, "node " + std::to_string(i) + " has a bad child index");
            }
            if (!contains(n.box, nodes[ch].box)) {
                return Result::fail(Status::kInternal, 0,
                                    "node " + std::to_string(i) + " box " + box_str(n.box) +
                                        " does not contain child " + std::to_string(ch) + " box " +
                                        box_str(nodes[ch].box));
            }
        }
        if (n.child[0] != i + 1) {
            return Result::fail(Status::kInternal, 0,
                                "node " + std::to_string(i) + ": left child is not the next node");
        }
        stack.push_back(n.child[1]);
        stack.push_back(n.child[0]);
    }
    if (expect != nodes.size()) {
        return Result::fail(Status::kInternal, 0, "unreachable nodes: " + std::to_string(nodes.size() - expect));
    }
    if (leaves != bvh.references) {
        return Result::fail(Status::kInternal, 0,
                            "references " + std::to_string(bvh.references) + " != leaves " + std::to_string(leaves));
    }
    for (size_t t = 0; t < tris; ++t) {
        if (leaves_of[t].empty()) {
            return Result::fail(Status::kInternal, 0, "triangle " + std::to_string(t) + " is in no leaf");
        }
    }
    // Coverage: random points on random triangles (some exactly at vertices
    // and on edges) must lie in one of that triangle's reference boxes.
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (int s = 0; s < samples; ++s) {
        const size_t t = size_t(rng() % tris);
        const auto tri = scene.triangle(t);
        double w1 = u01(rng), w2 = u01(rng);
        if (w1 + w2 > 1.0) { w1 = 1.0 - w1; w2 = 1.0 - w2; }
        switch (s % 8) {
            case 0: w1 = 0; w2 = 0; break;          // vertex 0
            case 1: w1 = 1; w2 = 0; break;          // vertex 1
            case 2: w1 = 0; w2 = 1; break;          // vertex 2
            case 3: w2 = 1.0 - w1; break;           // edge v1-v2
            case 4: w2 = 0; break;                  // edge v0-v1
            default: break;
        }
        double p[3], tol[3];
        for (int j = 0; j < 3; ++j) {
            // a + w1 (b - a) + w2 (c - a): exact on flat axes.
            p[j] = double(tri[0][j]) + w1 * (double(tri[1][j]) - tri[0][j]) + w2 * (double(tri[2][j]) - tri[0][j]);
            const double m =
                std::max({std::fabs(double(tri[0][j])), std::fabs(double(tri[1][j])), std::fabs(double(tri[2][j]))});
            tol[j] = 1e-12 * m;  // double evaluation error, far below one float ulp
        }
        bool inside = false;
        for (const uint32_t li : leaves_of[t]) {
            const Aabb& b = nodes[li].box;
            bool in = true;
            for (int j = 0; j < 3; ++j) in = in && b.lo[j] - tol[j] <= p[j] && p[j] <= b.hi[j] + tol[j];
            if (in) { inside = true; break; }
        }
        if (!inside) {
            char buf[160];
            std::snprintf(buf, sizeof buf,
                          "point (%.17g %.17g %.17g) of triangle %zu is in none of its %zu reference boxes", p[0], p[1],
                          p[2], t, leaves_of[t].size());
            return Result::fail(Status::kInternal, 0, buf);
        }
    }
    return Result::success();
}

}  // namespace cwbvh::compiler
