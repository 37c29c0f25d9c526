// Two-level test scenes built in memory (until cwbvhc writes two-level files, and
// afterwards for the adversarial cases no glTF holds): the bottom levels are the
// compiler core's trees of each mesh (build_wide), concatenated with absolute
// indices (spec 3.10); the top level is a small test-only 8-wide tree over the
// instance world boxes, quantized with the core's conservative quantizer
// (quantize_node), so every slot box contains its instances' world boxes. The
// flattened twin (every placement's triangles moved to world space, in double,
// rounded once) is compiled by the same core.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <deque>
#include <stdexcept>
#include <vector>

#include "cwbvh/compiler/quantize.h"
#include "cwbvh/kernels/traverse_two_level.h"
#include "test_scenes.h"

namespace cwbvh::test {

/// One placement: mesh index and object-to-world 3x4 (row-major, float as stored).
struct Placement {
    uint32_t mesh;
    float m[3][4];
};

inline Placement make_placement(uint32_t mesh, const double (&m)[3][4]) {
    Placement p{mesh, {}};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) p.m[r][c] = float(m[r][c]);
    return p;
}

/// float x rounded toward -inf (down) or +inf (up): conservative boxes.
inline float round_down(double x) {
    float f = float(x);
    if (double(f) > x) f = std::nextafter(f, -INFINITY);
    return f;
}
inline float round_up(double x) {
    float f = float(x);
    if (double(f) < x) f = std::nextafter(f, INFINITY);
    return f;
}

/// The exact (double) inverse of a 3x4 affine map given in float.
inline void invert_affine(const float (&m)[3][4], double (&inv)[3][4]) {
    const double a = m[0][0], b = m[0][1], c = m[0][2], d = m[1][0], e = m[1][1], f = m[1][2], g = m[2][0],
                 h = m[2][1], i = m[2][2];
    const double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    if (!(det != 0.0) || !std::isfinite(det)) throw std::runtime_error("invert_affine: singular transform");
    const double r[3][3] = {{(e * i - f * h) / det, (c * h - b * i) / det, (b * f - c * e) / det},
                            {(f * g - d * i) / det, (a * i - c * g) / det, (c * d - a * f) / det},
                            {(d * h - e * g) / det, (b * g - a * h) / det, (a * e - b * d) / det}};
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) inv[row][col] = r[row][col];
        inv[row][3] = -(r[row][0] * m[0][3] + r[row][1] * m[1][3] + r[row][2] * m[2][3]);
    }
}

/// x_world = M x (double from the float matrix and point).
inline void apply_affine(const float (&m)[3][4], const float* p, double* out) {
    for (int r = 0; r < 3; ++r)
        out[r] = double(m[r][0]) * p[0] + double(m[r][1]) * p[1] + double(m[r][2]) * p[2] + double(m[r][3]);
}

/// Test-only TLAS over `boxes` (one per instance): top-down, at most 24 instances
/// in a node's leaves (3 per slot), otherwise 8 equal groups along the widest
/// centroid axis. Internal children are allocated in slot order after child_base
/// (index = child_base + popc(imask below the slot), as the traversal decodes).
/// `order` receives the INST order (TLAS leaf order): INST k is input order[k].
inline void build_test_tlas(const std::vector<compiler::Aabb>& boxes, std::vector<CwbvhNode>& tlas,
                            std::vector<uint32_t>& order) {
    struct Job {
        uint32_t node;
        std::vector<uint32_t> items;
    };
    tlas.assign(1, CwbvhNode{});
    order.clear();
    std::deque<Job> jobs;
    Job root{0, {}};
    for (uint32_t i = 0; i < uint32_t(boxes.size()); ++i) root.items.push_back(i);
    jobs.push_back(std::move(root));
    while (!jobs.empty()) {
        Job job = std::move(jobs.front());
        jobs.pop_front();
        std::vector<uint32_t>& it = job.items;
        const size_t n = it.size();
        std::vector<std::vector<uint32_t>> groups;
        if (n <= size_t(kMaxNodeTriangles)) {
            for (size_t i = 0; i < n; i += 3) groups.emplace_back(it.begin() + i, it.begin() + std::min(n, i + 3));
        } else {
            double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
            auto centre = [&](uint32_t k, int a) { return 0.5 * (double(boxes[k].lo[a]) + boxes[k].hi[a]); };
            for (uint32_t k : it)
                for (int a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], centre(k, a));
                    hi[a] = std::max(hi[a], centre(k, a));
                }
            int axis = 0;
            for (int a = 1; a < 3; ++a)
                if (hi[a] - lo[a] > hi[axis] - lo[axis]) axis = a;
            std::stable_sort(it.begin(), it.end(),
                             [&](uint32_t x, uint32_t y) { return centre(x, axis) < centre(y, axis); });
            for (size_t g = 0; g < 8; ++g)
                groups.emplace_back(it.begin() + g * n / 8, it.begin() + (g + 1) * n / 8);
        }
        compiler::Aabb slot_boxes[8];
        uint8_t used = 0, imask = 0;
        uint8_t meta[8] = {};
        const uint32_t child_base = uint32_t(tlas.size());
        const uint32_t tri_base = uint32_t(order.size());
        for (size_t s = 0; s < groups.size(); ++s) {
            const std::vector<uint32_t>& g = groups[s];
            for (uint32_t k : g) slot_boxes[s].grow(boxes[k]);
            used |= uint8_t(1u << s);
            if (g.size() <= 3 && n <= 31) {
                const uint32_t offset = uint32_t(order.size()) - tri_base;
                meta[s] = uint8_t((((1u << g.size()) - 1u) << 5) | offset);
                order.insert(order.end(), g.begin(), g.end());
            } else {
                meta[s] = uint8_t(0x20u | (24u + uint32_t(s)));
                imask |= uint8_t(1u << s);
                jobs.push_back(Job{uint32_t(tlas.size()), g});
                tlas.push_back(CwbvhNode{});
            }
        }
        CwbvhNode node{};
        const Result q = compiler::quantize_node(slot_boxes, used, node);
        if (!q.ok()) throw std::runtime_error("test TLAS: " + q.message);
        node.imask = imask;
        node.child_base = imask ? child_base : 0u;
        node.tri_base = tri_base;
        std::copy(meta, meta + 8, node.meta);
        tlas[job.node] = node;
    }
}

/// A two-level scene in memory and its flattened twin.
struct TwoLevelBuild {
    std::vector<CwbvhNode> tlas;
    std::vector<InstanceRecord> instances;  ///< INST, TLAS leaf order
    std::vector<uint32_t> inst_placement;   ///< INST index -> placement index
    std::vector<MeshRecord> meshes;
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRecord> tris;
    std::vector<std::vector<TriangleRecord>> mesh_tris;  ///< per mesh, object space, prim = local index

    TwoLevelScene view() const {
        return TwoLevelScene{tlas.data(),   uint32_t(tlas.size()),   instances.data(), uint32_t(instances.size()),
                             meshes.data(), uint32_t(meshes.size()), nodes.data(),     uint32_t(nodes.size()),
                             tris.data(),   uint32_t(tris.size())};
    }
    /// The world-space triangle of (INST index, global prim): vertices in double.
    void world_triangle(uint32_t inst, uint32_t prim, double (&v)[3][3]) const {
        const InstanceRecord& r = instances[inst];
        const MeshRecord& m = meshes[r.mesh];
        const TriangleRecord& t = mesh_tris[r.mesh][prim - m.prim_first];
        apply_affine(r.object_to_world, t.v0, v[0]);
        apply_affine(r.object_to_world, t.v1, v[1]);
        apply_affine(r.object_to_world, t.v2, v[2]);
    }
};

inline TwoLevelBuild build_two_level(const std::vector<std::vector<TriangleRecord>>& mesh_tris,
                                     const std::vector<Placement>& placements) {
    TwoLevelBuild b;
    b.mesh_tris = mesh_tris;
    for (auto& mt : b.mesh_tris)
        for (uint32_t i = 0; i < uint32_t(mt.size()); ++i) mt[i].prim = i;
    uint32_t prim_first = 0;
    for (const auto& mt : b.mesh_tris) {
        WideBvh w = build_wide(mt);
        MeshRecord m{};
        m.node_first = uint32_t(b.nodes.size());
        m.node_count = uint32_t(w.nodes.size());
        m.tri_first = uint32_t(b.tris.size());
        m.tri_count = uint32_t(w.tris.size());
        m.prim_first = prim_first;
        m.prim_count = uint32_t(mt.size());
        for (int a = 0; a < 3; ++a) {
            m.lo[a] = INFINITY;
            m.hi[a] = -INFINITY;
        }
        for (const TriangleRecord& t : mt)
            for (const float* v : {t.v0, t.v1, t.v2})
                for (int a = 0; a < 3; ++a) {
                    m.lo[a] = std::min(m.lo[a], v[a]);
                    m.hi[a] = std::max(m.hi[a], v[a]);
                }
        m.source_mesh = kInvalidIndex;
        for (CwbvhNode& n : w.nodes) {
            if (n.imask) n.child_base += m.node_first;
            n.tri_base += m.tri_first;
        }
        for (TriangleRecord& t : w.tris) t.prim += prim_first;
        b.nodes.insert(b.nodes.end(), w.nodes.begin(), w.nodes.end());
        b.tris.insert(b.tris.end(), w.tris.begin(), w.tris.end());
        b.meshes.push_back(m);
        prim_first += uint32_t(mt.size());
    }
    std::vector<InstanceRecord> recs;
    std::vector<compiler::Aabb> boxes;
    for (const Placement& p : placements) {
        InstanceRecord r{};
        double inv[3][4];
        invert_affine(p.m, inv);
        for (int row = 0; row < 3; ++row)
            for (int col = 0; col < 4; ++col) {
                r.object_to_world[row][col] = p.m[row][col];
                r.world_to_object[row][col] = float(inv[row][col]);
            }
        r.mesh = p.mesh;
        r.source_node = kInvalidIndex;
        const MeshRecord& m = b.meshes.at(p.mesh);
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (int c = 0; c < 8; ++c) {
            const float corner[3] = {(c & 1) ? m.hi[0] : m.lo[0], (c & 2) ? m.hi[1] : m.lo[1],
                                     (c & 4) ? m.hi[2] : m.lo[2]};
            double w[3];
            apply_affine(p.m, corner, w);
            for (int a = 0; a < 3; ++a) {
                lo[a] = std::min(lo[a], w[a]);
                hi[a] = std::max(hi[a], w[a]);
            }
        }
        compiler::Aabb box;
        for (int a = 0; a < 3; ++a) {
            r.world_lo[a] = box.lo[a] = round_down(lo[a]);
            r.world_hi[a] = box.hi[a] = round_up(hi[a]);
        }
        recs.push_back(r);
        boxes.push_back(box);
    }
    build_test_tlas(boxes, b.tlas, b.inst_placement);
    for (uint32_t k : b.inst_placement) b.instances.push_back(recs[k]);
    return b;
}

/// The flattened twin: every instance's triangles in world space (double, rounded
/// once to float), compiled by the core. flat_of[i] = {INST index, global prim} of
/// flattened triangle i (its prim).
struct FlatBuild {
    WideBvh wide;
    std::vector<std::pair<uint32_t, uint32_t>> source;  ///< flattened prim -> (INST, global prim)
};

inline FlatBuild flatten(const TwoLevelBuild& b) {
    FlatBuild f;
    std::vector<TriangleRecord> all;
    for (uint32_t i = 0; i < uint32_t(b.instances.size()); ++i) {
        const InstanceRecord& r = b.instances[i];
        const MeshRecord& m = b.meshes[r.mesh];
        for (const TriangleRecord& t : b.mesh_tris[r.mesh]) {
            double v[3][3];
            b.world_triangle(i, m.prim_first + t.prim, v);
            float fv[3][3];
            for (int k = 0; k < 3; ++k)
                for (int a = 0; a < 3; ++a) fv[k][a] = float(v[k][a]);
            all.push_back(make_tri(fv[0], fv[1], fv[2], uint32_t(all.size())));
            f.source.emplace_back(i, m.prim_first + t.prim);
        }
    }
    f.wide = build_wide(all);
    return f;
}

}  // namespace cwbvh::test
