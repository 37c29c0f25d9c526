// Scenes and meshes for the traversal tests. The trees are the compiler core's
// (compiler/include/cwbvh/compiler/core.h: SBVH, collapse, auction slots,
// quantization, encoding), so the tests trace what cwbvhc ships.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "../result_util.h"
#include "cwbvh/compiler/core.h"
#include "cwbvh/format/format.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/tree_depth.h"
#include "cwbvh/kernels/ray.h"

namespace cwbvh::test {

inline TriangleRecord make_tri(const float* a, const float* b, const float* c, uint32_t prim) {
    TriangleRecord t{};
    for (int i = 0; i < 3; ++i) {
        t.v0[i] = a[i];
        t.v1[i] = b[i];
        t.v2[i] = c[i];
    }
    t.prim = prim;
    return t;
}

/// The wide tree (NODE) and its triangle records (TRIS) of a test scene.
struct WideBvh {
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRecord> tris;
    int depth = 0;  ///< levels of NODE (root = 1)
};

/// The compiler core's scene of `tris`: stored triangle i is record i (its
/// three vertices as they are, nothing dropped), one source primitive.
inline compiler::Scene core_scene(const std::vector<TriangleRecord>& tris) {
    compiler::Scene scene;
    for (uint32_t i = 0; i < uint32_t(tris.size()); ++i) {
        for (const float* v : {tris[i].v0, tris[i].v1, tris[i].v2}) scene.vertices.push_back({v[0], v[1], v[2]});
        scene.indices.push_back({3 * i, 3 * i + 1, 3 * i + 2});
        scene.sources.push_back({0, 0, 0, i});
    }
    scene.input_triangles = tris.size();
    scene.input_names.push_back("test");
    return scene;
}

/// Compiles `tris` through the compiler core as cwbvhc compiles a mesh (SBVH,
/// collapse, slots, quantization, encoding; the core's verify pass included).
inline compiler::EmitResult core_compile(const std::vector<TriangleRecord>& tris, compiler::Bvh2Section bvh2) {
    compiler::CoreOptions options;
    options.emit.bvh2 = bvh2;
    compiler::EmitResult out;
    std::string error;
    if (!::cwbvh::test::ok(compiler::compile_scene(core_scene(tris), options, out), error))
        throw std::runtime_error("test scene: the compiler core failed: " + error);
    return out;
}

/// The core's wide tree over `input`. TRIS is the core's (leaf order); each
/// record keeps its input record's prim (the core's prim is the input index).
inline WideBvh build_wide(const std::vector<TriangleRecord>& input) {
    compiler::EmitResult e = core_compile(input, compiler::Bvh2Section::kNone);
    WideBvh out;
    out.nodes = std::move(e.tree.nodes);
    out.tris = std::move(e.tree.triangles);
    for (TriangleRecord& t : out.tris) t.prim = input[t.prim].prim;
    out.depth = int(wide_tree_depth(out.nodes));
    return out;
}

struct Bvh2 {
    std::vector<Bvh2Node> nodes;
    int depth = 0;  ///< levels incl. leaves
};

/// The core's BVH2 (the binary SBVH, one triangle per leaf) over `tris`, its
/// leaves re-indexed from the core's TRIS to `tris` (leaf = ~input index), so it
/// traces over `tris` as it is.
inline Bvh2 build_bvh2(const std::vector<TriangleRecord>& tris) {
    const compiler::EmitResult e = core_compile(tris, compiler::Bvh2Section::kBvh2);
    Bvh2 out;
    out.nodes = e.tree.bvh2;
    for (Bvh2Node& n : out.nodes)
        for (int32_t& c : n.child)
            if (c < 0) c = ~int32_t(e.tree.triangles[uint32_t(~c)].prim);
    out.depth = int(bvh2_tree_depth(out.nodes));
    return out;
}

// ---------------------------------------------------------------------------
// Meshes (indexed, so shared vertices are bitwise identical)
// ---------------------------------------------------------------------------

struct Mesh {
    std::vector<float> v;  // xyz
    std::vector<uint32_t> idx;
    std::vector<TriangleRecord> tris() const {
        std::vector<TriangleRecord> t;
        for (size_t i = 0; i + 2 < idx.size(); i += 3)
            t.push_back(make_tri(&v[idx[i] * 3], &v[idx[i + 1] * 3], &v[idx[i + 2] * 3], uint32_t(i / 3)));
        return t;
    }
    void transform(double scale, double offset) {
        for (float& x : v) x = float(double(x) * scale + offset);
    }
};

/// n x n quads on integer coordinates, z = small integer bumps, alternating diagonals.
inline Mesh grid_mesh(int n, bool bumpy = true) {
    Mesh m;
    for (int j = 0; j <= n; ++j)
        for (int i = 0; i <= n; ++i) {
            m.v.push_back(float(i));
            m.v.push_back(float(j));
            m.v.push_back(bumpy ? float(((i * 7 + j * 3) % 5) - 2) * 0.5f : 0.0f);
        }
    auto id = [n](int i, int j) { return uint32_t(j * (n + 1) + i); };
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            if ((i + j) & 1) m.idx.insert(m.idx.end(), {a, b, c, a, c, d});
            else m.idx.insert(m.idx.end(), {a, b, d, b, c, d});
        }
    return m;
}

/// Closed cube surface [0, n]^3 with n x n quads per face; `sphere` projects the
/// vertices onto a sphere of radius n/2 around the center (still closed: indexed).
inline Mesh cube_mesh(int n, bool sphere = false) {
    Mesh m;
    std::vector<int> key((n + 1) * (n + 1) * (n + 1), -1);
    auto vid = [&](int x, int y, int z) {
        int& k = key[(z * (n + 1) + y) * (n + 1) + x];
        if (k < 0) {
            k = int(m.v.size() / 3);
            double p[3] = {double(x), double(y), double(z)};
            if (sphere) {
                const double c = n * 0.5;
                double d[3] = {p[0] - c, p[1] - c, p[2] - c};
                const double l = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                for (int a = 0; a < 3; ++a) p[a] = c + d[a] / l * c;
            }
            for (int a = 0; a < 3; ++a) m.v.push_back(float(p[a]));
        }
        return uint32_t(k);
    };
    for (int face = 0; face < 6; ++face) {
        const int axis = face / 2, side = (face & 1) ? n : 0;
        const int u = (axis + 1) % 3, w = (axis + 2) % 3;
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                auto corner = [&](int di, int dj) {
                    int c[3];
                    c[axis] = side;
                    c[u] = i + di;
                    c[w] = j + dj;
                    return vid(c[0], c[1], c[2]);
                };
                const uint32_t a = corner(0, 0), b = corner(1, 0), c = corner(1, 1), d = corner(0, 1);
                if ((i + j + face) & 1) m.idx.insert(m.idx.end(), {a, b, c, a, c, d});
                else m.idx.insert(m.idx.end(), {a, b, d, b, c, d});
            }
    }
    return m;
}

/// Random triangle soup in [0, extent]^3, triangle size ~ size.
inline std::vector<TriangleRecord> random_soup(size_t count, float extent, float size, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> pos(0.0f, extent), off(-size, size);
    std::vector<TriangleRecord> t;
    for (size_t i = 0; i < count; ++i) {
        float c[3] = {pos(rng), pos(rng), pos(rng)}, a[3], b[3], d[3];
        for (int k = 0; k < 3; ++k) {
            a[k] = c[k] + off(rng);
            b[k] = c[k] + off(rng);
            d[k] = c[k] + off(rng);
        }
        t.push_back(make_tri(a, b, d, uint32_t(i)));
    }
    return t;
}

inline Ray make_ray(const float* o, const float* d, float tmin = 0.0f, float tmax = INFINITY) {
    Ray r;
    for (int a = 0; a < 3; ++a) {
        r.org[a] = o[a];
        r.dir[a] = d[a];
    }
    r.tmin = tmin;
    r.tmax = tmax;
    return r;
}

}  // namespace cwbvh::test
