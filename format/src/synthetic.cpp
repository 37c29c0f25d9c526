#include "cwbvh/synthetic.h"

#include <algorithm>
#include <cmath>
#include <deque>

#include "cwbvh/node_decode.h"
#include "cwbvh/source_map.h"

namespace cwbvh {
namespace {

struct Box {
    float lo[3] = {INFINITY, INFINITY, INFINITY};
    float hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    void grow(const float* v) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], v[a]);
            hi[a] = std::max(hi[a], v[a]);
        }
    }
    void grow(const TriangleRecord& t) { grow(t.v0); grow(t.v1); grow(t.v2); }
};

uint64_t splitmix(uint64_t& s) {
    uint64_t z = (s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

uint32_t compact_bits(uint32_t v) {  // every third bit of a Morton code
    uint32_t r = 0;
    for (int i = 0; i < 10; ++i) r |= ((v >> (3 * i)) & 1u) << i;
    return r;
}

struct Child {
    uint32_t begin, end;  ///< range of source triangles
    bool leaf;
};

/// Partition of [b, e) into the children of one node (see header).
std::vector<Child> partition(uint32_t b, uint32_t e) {
    std::vector<Child> out;
    const uint32_t n = e - b;
    if (n <= uint32_t(kMaxNodeTriangles)) {
        for (uint32_t i = b; i < e; i += 3) out.push_back({i, std::min(e, i + 3), true});
        return out;
    }
    const uint32_t first = 1 + n % 3;
    out.push_back({b, b + first, true});
    const uint32_t rest = n - first;
    for (uint32_t k = 0; k < 7; ++k) {
        const uint32_t cb = b + first + rest * k / 7, ce = b + first + rest * (k + 1) / 7;
        if (ce > cb) out.push_back({cb, ce, ce - cb <= 3});
    }
    return out;
}

/// Conservative quantization of one axis by decode-and-correct: the decoded
/// planes (normative decode, decode_plane) must satisfy lo <= child lo and
/// hi >= child hi. Starts from the smallest scale that can fit and grows it
/// when a plane would need q > 255.
void quantize_axis(CwbvhNode& n, int a, const std::vector<Box>& boxes, const std::vector<int>& slots) {
    const float p = n.p[a];
    double ext = 0;
    for (const Box& b : boxes) ext = std::max(ext, double(b.hi[a]) - double(p));
    int k = -126;
    if (ext > 0) k = std::max(-126, int(std::ceil(std::log2(ext / 255.0))));
    for (;; ++k) {
        n.e[a] = uint8_t(k + 127);
        bool fits = true;
        for (size_t c = 0; c < boxes.size() && fits; ++c) {
            const int s = slots[c];
            const double scale = std::ldexp(1.0, k);
            double qlo = std::clamp(std::floor((double(boxes[c].lo[a]) - p) / scale), 0.0, 255.0);
            // Rounding: lower plane must round down (never above the child's lo).
            while (qlo > 0 && decode_plane(p, n.e[a], uint8_t(qlo)) > boxes[c].lo[a]) qlo -= 1;
            double qhi = std::clamp(std::ceil((double(boxes[c].hi[a]) - p) / scale), qlo, 256.0);
            // Upper plane must round up (never below the child's hi).
            while (qhi <= 255 && decode_plane(p, n.e[a], uint8_t(qhi)) < boxes[c].hi[a]) qhi += 1;
            fits = qhi <= 255;
            n.q_lo[a][s] = uint8_t(qlo);
            n.q_hi[a][s] = uint8_t(std::min(qhi, 255.0));
        }
        if (fits) return;
    }
}

/// Median split over records [b, e); a child range of at most max_leaf records
/// is a leaf (max_leaf 1: one record, leaf_count 0 as BVH2 wants; more: BV2L counts).
uint32_t build_bvh2(std::vector<Bvh2Node>& out, const std::vector<Box>& boxes, uint32_t b, uint32_t e,
                    uint32_t max_leaf) {
    const uint32_t index = uint32_t(out.size());
    out.emplace_back();
    const uint32_t mid = b + (e - b) / 2;
    const uint32_t ranges[2][2] = {{b, mid}, {mid, e}};
    Box child_box[2];
    int32_t child[2];
    uint32_t leaf_count[2] = {0, 0};
    for (int c = 0; c < 2; ++c) {
        const uint32_t cb = ranges[c][0], ce = ranges[c][1];
        for (uint32_t i = cb; i < ce; ++i) {
            child_box[c].grow(boxes[i].lo);
            child_box[c].grow(boxes[i].hi);
        }
        const bool leaf = ce - cb <= max_leaf;
        child[c] = leaf ? ~int32_t(cb) : int32_t(build_bvh2(out, boxes, cb, ce, max_leaf));
        if (leaf && max_leaf > 1) leaf_count[c] = ce - cb;
    }
    Bvh2Node& n = out[index];
    n = Bvh2Node{child_box[0].lo[0], child_box[0].hi[0], child_box[0].lo[1], child_box[0].hi[1],
                 child_box[1].lo[0], child_box[1].hi[0], child_box[1].lo[1], child_box[1].hi[1],
                 child_box[0].lo[2], child_box[0].hi[2], child_box[1].lo[2], child_box[1].hi[2],
                 {child[0], child[1]}, {leaf_count[0], leaf_count[1]}};
    return index;
}

}  // namespace

SceneData make_synthetic_scene(const SyntheticOptions& options) {
    SceneData scene;
    const uint32_t count = options.triangles;
    // Source triangles on a Morton-ordered grid: consecutive ids are close.
    std::vector<TriangleRecord> source(count);
    uint64_t rng = options.seed;
    for (uint32_t i = 0; i < count; ++i) {
        const float cell[3] = {float(compact_bits(i)), float(compact_bits(i >> 1)), float(compact_bits(i >> 2))};
        float* v[3] = {source[i].v0, source[i].v1, source[i].v2};
        for (float* vertex : v)
            for (int a = 0; a < 3; ++a) vertex[a] = cell[a] + float(splitmix(rng) >> 40) / float(1u << 24);
        source[i].prim = i;
    }
    Box scene_box;
    for (const TriangleRecord& t : source) scene_box.grow(t);
    auto range_box = [&](uint32_t b, uint32_t e) {
        Box box;
        for (uint32_t i = b; i < e; ++i) box.grow(source[i]);
        return box;
    };

    // Breadth-first: a node's internal children get consecutive indices.
    struct Todo { uint32_t node, begin, end; };
    std::deque<Todo> todo{{0, 0, count}};
    scene.nodes.emplace_back();
    uint64_t children_total = 0;
    while (!todo.empty()) {
        const Todo t = todo.front();
        todo.pop_front();
        const std::vector<Child> children = t.end > t.begin ? partition(t.begin, t.end) : std::vector<Child>{};
        CwbvhNode n{};
        n.e[0] = n.e[1] = n.e[2] = 127;
        const Box box = range_box(t.begin, t.end);
        std::vector<Box> boxes;
        std::vector<int> slots;
        n.child_base = uint32_t(scene.nodes.size());
        n.tri_base = uint32_t(scene.triangles.size());
        int offset = 0;
        for (size_t j = 0; j < children.size(); ++j) {
            const Child& c = children[j];
            const int s = int(j * kWidth / children.size());  // spreads children, leaving gaps
            slots.push_back(s);
            boxes.push_back(range_box(c.begin, c.end));
            if (c.leaf) {
                n.meta[s] = make_meta_leaf(int(c.end - c.begin), offset);
                offset += int(c.end - c.begin);
                for (uint32_t i = c.begin; i < c.end; ++i) scene.triangles.push_back(source[i]);
            } else {
                n.meta[s] = make_meta_internal(s);
                n.imask |= uint8_t(1u << s);
                todo.push_back({uint32_t(scene.nodes.size()), c.begin, c.end});
                scene.nodes.emplace_back();
            }
        }
        if (n.imask == 0) n.child_base = 0;
        if (offset == 0) n.tri_base = 0;
        if (!children.empty()) {
            for (int a = 0; a < 3; ++a) n.p[a] = box.lo[a];
            for (int a = 0; a < 3; ++a) quantize_axis(n, a, boxes, slots);
        }
        children_total += children.size();
        scene.nodes[t.node] = n;
    }

    // Primitives of 8 triangles, so PMAP holds several runs.
    std::vector<SourceRef> refs;
    for (uint32_t i = 0; i < count; ++i) refs.push_back({0, 0, i / 8, i % 8});
    scene.source_ranges = make_source_ranges(refs);
    if (count > 0)
        for (int a = 0; a < 3; ++a) {
            scene.bounds.lo[a] = scene_box.lo[a];
            scene.bounds.hi[a] = scene_box.hi[a];
        }
    if (options.bvh2 && count > 0) {
        std::vector<Box> ref_boxes(scene.triangles.size());
        for (size_t i = 0; i < scene.triangles.size(); ++i) ref_boxes[i].grow(scene.triangles[i]);
        // BV2L: leaves of up to 3 consecutive records (as cwbvhc's, whose leaves are the wide tree's).
        const uint32_t max_leaf = options.bvh2_leaf_ranges ? uint32_t(kMaxLeafTriangles) : 1u;
        scene.bvh2_leaf_ranges = options.bvh2_leaf_ranges;
        if (count == 1) {  // a 1-reference scene duplicates its leaf in both children
            const Box& b = ref_boxes[0];
            const uint32_t lc = options.bvh2_leaf_ranges ? 1u : 0u;
            scene.bvh2.push_back(Bvh2Node{b.lo[0], b.hi[0], b.lo[1], b.hi[1], b.lo[0], b.hi[0], b.lo[1], b.hi[1],
                                          b.lo[2], b.hi[2], b.lo[2], b.hi[2], {~0, ~0}, {lc, lc}});
        } else {
            build_bvh2(scene.bvh2, ref_boxes, 0, uint32_t(ref_boxes.size()), max_leaf);
        }
    }
    if (options.source_geometry && count > 0) {
        for (uint32_t i = 0; i < count; ++i) {
            for (const float* v : {source[i].v0, source[i].v1, source[i].v2})
                scene.vertices.insert(scene.vertices.end(), v, v + 3);
            for (uint32_t k = 0; k < 3; ++k) scene.indices.push_back(3 * i + k);
        }
        scene.source_names = std::string("synthetic") + '\0';
    }
    if (options.build_info) {
        BuildInfo b{};
        b.builder = kBuilderSbvh;
        b.collapse = kCollapseOptimal;
        b.split_alpha = 1e-5f;
        b.cost_node = 1.0f;
        b.cost_prim = 0.3f;
        b.max_leaf_triangles = kMaxLeafTriangles;
        b.input_triangles = b.triangles = b.references = count;
        b.binary_nodes = count == 0 ? 0 : 2ull * count - 1;
        b.wide_nodes = scene.nodes.size();
        b.avg_children = double(children_total) / double(scene.nodes.size());
        scene.build_info = b;
    }
    return scene;
}

}  // namespace cwbvh
