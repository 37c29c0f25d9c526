#include "format/two_level_scene.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "cwbvh/compiler/quantize.h"
#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/transform_host.h"

namespace cwbvh::test {
namespace {

compiler::Aabb box_of(const float lo[3], const float hi[3]) {
    compiler::Aabb b;
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = lo[a];
        b.hi[a] = hi[a];
    }
    return b;
}

void grow(compiler::Aabb& b, const compiler::Aabb& o) {
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = std::min(b.lo[a], o.lo[a]);
        b.hi[a] = std::max(b.hi[a], o.hi[a]);
    }
}

/// Quantizes `node` for the used slots' boxes; throws if the core refuses.
void quantize(CwbvhNode& node, const compiler::Aabb (&boxes)[8], uint8_t used) {
    if (const Result r = compiler::quantize_node(boxes, used, node); !r.ok()) throw std::runtime_error(r.describe());
}

}  // namespace

Placement place(uint32_t mesh, float tx, float ty, float tz, float degrees, float scale, bool mirror_x) {
    Placement p{};
    p.mesh = mesh;
    const double r = double(degrees) * 3.14159265358979323846 / 180.0;
    const float c = float(std::cos(r)) * scale, s = float(std::sin(r)) * scale;
    const float m[3][4] = {{c, -s, 0, tx}, {s, c, 0, ty}, {0, 0, scale, tz}};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 4; ++j) p.object_to_world[i][j] = m[i][j];
    if (mirror_x)
        for (int i = 0; i < 3; ++i) p.object_to_world[i][0] = -p.object_to_world[i][0];
    return p;
}

SceneData make_two_level(const std::vector<SceneData>& meshes, const std::vector<Placement>& placements) {
    SceneData s;
    // Bottom levels, one after another, every index absolute (spec 3.9).
    for (size_t m = 0; m < meshes.size(); ++m) {
        const SceneData& in = meshes[m];
        MeshRecord rec{};
        rec.node_first = uint32_t(s.nodes.size());
        rec.node_count = uint32_t(in.nodes.size());
        rec.tri_first = uint32_t(s.triangles.size());
        rec.tri_count = uint32_t(in.triangles.size());
        rec.prim_first = s.source_ranges.empty() ? 0 : s.source_ranges.back().first + s.source_ranges.back().count;
        rec.prim_count = in.source_ranges.back().first + in.source_ranges.back().count;
        rec.source_mesh = uint32_t(m);
        for (CwbvhNode n : in.nodes) {
            if (n.imask != 0) n.child_base += rec.node_first;
            bool leaves = false;
            for (int sl = 0; sl < kWidth; ++sl) leaves |= !meta_is_empty(n.meta[sl]) && !meta_is_internal(n.meta[sl]);
            if (leaves) n.tri_base += rec.tri_first;
            s.nodes.push_back(n);
        }
        for (int a = 0; a < 3; ++a) {
            rec.lo[a] = INFINITY;
            rec.hi[a] = -INFINITY;
        }
        for (TriangleRecord t : in.triangles) {
            t.prim += rec.prim_first;
            for (const float* v : {t.v0, t.v1, t.v2})
                for (int a = 0; a < 3; ++a) {
                    rec.lo[a] = std::min(rec.lo[a], v[a]);
                    rec.hi[a] = std::max(rec.hi[a], v[a]);
                }
            s.triangles.push_back(t);
        }
        for (SourceRange r : in.source_ranges) {
            r.first += rec.prim_first;
            r.mesh = uint32_t(m);
            s.source_ranges.push_back(r);
        }
        s.meshes.push_back(rec);
    }
    // Instances in TLAS leaf order: the root's leaf first, then the internal children's.
    for (const Placement& p : placements) {
        Expected<InstanceRecord> inst = make_instance(p.object_to_world, s.meshes.at(p.mesh), p.mesh, p.source_node);
        if (!inst.ok()) throw std::runtime_error(inst.error().describe());
        s.instances.push_back(*inst);
    }
    const size_t n = s.instances.size();
    auto world = [&](size_t i) { return box_of(s.instances[i].world_lo, s.instances[i].world_hi); };
    const size_t in_root = std::min<size_t>(2, n);
    const size_t children = (n - in_root + 7) / 8;
    if (children > 3) throw std::runtime_error("make_two_level: at most 26 instances");
    CwbvhNode root{};
    compiler::Aabb root_boxes[8];
    uint8_t used = 0;
    compiler::Aabb leaf = world(0);
    for (size_t i = 1; i < in_root; ++i) grow(leaf, world(i));
    root_boxes[0] = leaf;
    used |= 1;
    root.meta[0] = make_meta_leaf(int(in_root), 0);
    root.tri_base = 0;
    root.child_base = children ? 1u : 0u;
    std::vector<CwbvhNode> kids;
    for (size_t c = 0; c < children; ++c) {
        CwbvhNode kid{};
        compiler::Aabb boxes[8];
        uint8_t kid_used = 0;
        const size_t first = in_root + 8 * c, last = std::min(n, first + 8);
        compiler::Aabb all = world(first);
        for (size_t i = first; i < last; ++i) {
            const int slot = int(i - first);
            boxes[slot] = world(i);
            grow(all, world(i));
            kid_used = uint8_t(kid_used | (1u << slot));
            kid.meta[slot] = make_meta_leaf(1, slot);
        }
        kid.tri_base = uint32_t(first);
        quantize(kid, boxes, kid_used);
        kids.push_back(kid);
        const int slot = int(c) + 1;
        root_boxes[slot] = all;
        used = uint8_t(used | (1u << slot));
        root.meta[slot] = make_meta_internal(slot);
        root.imask = uint8_t(root.imask | (1u << slot));
    }
    quantize(root, root_boxes, used);
    s.top_nodes.push_back(root);
    for (const CwbvhNode& k : kids) s.top_nodes.push_back(k);
    compiler::Aabb all = world(0);
    for (size_t i = 1; i < n; ++i) grow(all, world(i));
    for (int a = 0; a < 3; ++a) {
        s.bounds.lo[a] = all.lo[a];
        s.bounds.hi[a] = all.hi[a];
    }
    return s;
}

SceneData standard_two_level() {
    SyntheticOptions a;
    a.triangles = 30;
    a.bvh2 = false;
    a.source_geometry = false;
    a.build_info = false;
    SyntheticOptions b = a;
    b.triangles = 10;
    b.seed = 2;
    const std::vector<SceneData> meshes = {make_synthetic_scene(a), make_synthetic_scene(b)};
    const std::vector<Placement> placements = {
        place(0), place(1, 5, 0, 0), place(0, 0, 6, 1, 30, 0.5f), place(1, -4, 2, 0, 90, 2, true),
        place(0, 1e4f, -2e4f, 3e3f, 45),
    };
    return make_two_level(meshes, placements);
}

}  // namespace cwbvh::test
