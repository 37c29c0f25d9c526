#include "wide/wide_test_util.h"

#include "build/test_mesh.h"

#include <algorithm>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

namespace cwbvh::wide_test {

uint32_t add_box(BinaryBvh& boxes, const Aabb& box) {
    compiler::BinaryNode n;
    n.box = box;
    boxes.nodes.push_back(n);
    return uint32_t(boxes.nodes.size() - 1);
}

compiler::WideChild leaf_of(const Scene& scene, BinaryBvh& boxes, uint32_t first, uint32_t count) {
    compiler::WideChild c;
    c.kind = compiler::WideChild::kLeaf;
    c.first_ref = first;
    c.ref_count = uint8_t(count);
    Aabb box;
    for (uint32_t k = 0; k < count; ++k)
        for (const auto& v : scene.triangle(first + k)) box.grow(v);
    c.bnode = add_box(boxes, box);
    return c;
}

Scene random_scene(size_t n, uint32_t seed, float extent, float size) {
    Scene s;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(0.0f, extent), off(-size, size);
    for (size_t i = 0; i < n; ++i) {
        const compiler::Vec3 c{pos(rng), pos(rng), pos(rng)};
        for (int k = 0; k < 3; ++k) s.vertices.push_back({c[0] + off(rng), c[1] + off(rng), c[2] + off(rng)});
        s.indices.push_back({uint32_t(3 * i), uint32_t(3 * i + 1), uint32_t(3 * i + 2)});
        s.sources.push_back({0, 0, 0, uint32_t(i)});
    }
    s.input_names = {"random"};
    s.input_triangles = n;
    return s;
}

namespace {
Aabb tri_box(const Scene& s, uint32_t t) {
    Aabb b;
    for (const auto& v : s.triangle(t)) b.grow(v);
    return b;
}
}  // namespace

BinaryBvh build_binary(const Scene& scene, std::vector<uint32_t> refs, SplitMode mode, uint32_t seed) {
    BinaryBvh bvh;
    std::mt19937 rng(seed);
    struct Range {
        size_t begin, end;
        uint32_t parent;
        int side;
    };
    std::vector<Range> stack{{0, refs.size(), kInvalidIndex, 0}};
    auto centre = [&](uint32_t t, int a) {
        const Aabb b = tri_box(scene, t);
        return 0.5f * (b.lo[a] + b.hi[a]);
    };
    while (!stack.empty()) {
        const Range r = stack.back();
        stack.pop_back();
        const uint32_t index = uint32_t(bvh.nodes.size());
        bvh.nodes.emplace_back();
        if (r.parent != kInvalidIndex) bvh.nodes[r.parent].child[r.side] = index;
        if (r.end - r.begin == 1) {
            bvh.nodes[index].set_prim(refs[r.begin]);
            continue;
        }
        size_t mid;
        if (mode == SplitMode::kChain) {
            mid = r.begin + 1;
        } else {
            Aabb cb;
            for (size_t i = r.begin; i < r.end; ++i) {
                const Aabb b = tri_box(scene, refs[i]);
                cb.grow(compiler::Vec3{0.5f * (b.lo[0] + b.hi[0]), 0.5f * (b.lo[1] + b.hi[1]),
                                       0.5f * (b.lo[2] + b.hi[2])});
            }
            int axis = 0;
            for (int a = 1; a < 3; ++a)
                if (cb.hi[a] - cb.lo[a] > cb.hi[axis] - cb.lo[axis]) axis = a;
            if (mode == SplitMode::kRandom) axis = int(rng() % 3);
            std::stable_sort(refs.begin() + long(r.begin), refs.begin() + long(r.end),
                             [&](uint32_t x, uint32_t y) { return centre(x, axis) < centre(y, axis); });
            mid = mode == SplitMode::kMedian ? (r.begin + r.end) / 2
                                             : r.begin + 1 + rng() % (r.end - r.begin - 1);
        }
        stack.push_back({mid, r.end, index, 1});
        stack.push_back({r.begin, mid, index, 0});
    }
    for (size_t i = bvh.nodes.size(); i-- > 0;) {
        compiler::BinaryNode& n = bvh.nodes[i];
        if (n.is_leaf()) {
            n.box = tri_box(scene, n.prim());
        } else {
            n.box = bvh.nodes[n.child[0]].box;
            n.box.grow(bvh.nodes[n.child[1]].box);
        }
    }
    bvh.references = refs.size();
    return bvh;
}

BinaryBvh build_binary(const Scene& scene, SplitMode mode, uint32_t seed) {
    std::vector<uint32_t> refs(scene.triangle_count());
    for (size_t i = 0; i < refs.size(); ++i) refs[i] = uint32_t(i);
    return build_binary(scene, std::move(refs), mode, seed);
}

bool read_obj(const std::string& path, Scene& scene) {
    // One test OBJ reader for the whole test tree (tests/build/test_mesh.h).
    const bool ok = compiler::test::read_obj(path, scene);
    scene.input_names = {path};
    return ok;
}

namespace {
struct Option {
    double cost;
    int exposed;  // roots handed to the nearest wide internal ancestor
};

struct Brute {
    const BinaryBvh& bvh;
    double c_node, c_prim;
    int max_leaf;

    void leaves(uint32_t n, std::vector<uint32_t>& prims) const {
        const auto& b = bvh.nodes[n];
        if (b.is_leaf()) {
            prims.push_back(b.prim());
            return;
        }
        leaves(b.child[0], prims);
        leaves(b.child[1], prims);
    }
    // Every configuration of n's subtree (no pruning by cost).
    std::vector<Option> all(uint32_t n) const {
        const auto& b = bvh.nodes[n];
        std::vector<Option> out;
        std::vector<uint32_t> prims;
        leaves(n, prims);
        if (int(prims.size()) <= max_leaf) {
            std::sort(prims.begin(), prims.end());
            const auto distinct = std::unique(prims.begin(), prims.end()) - prims.begin();
            out.push_back({c_prim * double(distinct) * b.box.half_area(), 1});  // wide leaf
        }
        if (b.is_leaf()) return out;
        const auto l = all(b.child[0]), r = all(b.child[1]);
        for (const Option& x : l) {
            for (const Option& y : r) {
                const int e = x.exposed + y.exposed;
                if (e <= 8) out.push_back({c_node * b.box.half_area() + x.cost + y.cost, 1});  // internal
                if (e <= 7) out.push_back({x.cost + y.cost, e});                               // eliminated
            }
        }
        return out;
    }
};
}  // namespace

double brute_force_min_cost(const BinaryBvh& bvh, double c_node, double c_prim, int max_leaf,
                            uint64_t* configurations) {
    Brute b{bvh, c_node, c_prim, max_leaf};
    const auto& root = bvh.nodes[0];
    double best = std::numeric_limits<double>::infinity();
    uint64_t count = 0;
    if (root.is_leaf()) {
        best = c_node * root.box.half_area() + c_prim * root.box.half_area();
        count = 1;
    } else {
        const auto l = b.all(root.child[0]), r = b.all(root.child[1]);
        for (const Option& x : l) {
            for (const Option& y : r) {
                if (x.exposed + y.exposed > 8) continue;
                ++count;
                best = std::min(best, c_node * root.box.half_area() + x.cost + y.cost);
            }
        }
    }
    if (configurations) *configurations = count;
    return best;
}

}  // namespace cwbvh::wide_test
