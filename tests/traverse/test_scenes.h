// Test-only tree builders and meshes for the traversal tests. NOT the compiler:
// a plain recursive median split into up to 8 children with <= 3 triangles per
// leaf, greedy octant slot assignment, and conservative quantization checked by
// decoding (decode_plane) and widening. Enough to exercise traversal logic.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "cwbvh/format.h"
#include "cwbvh/node_decode.h"
#include "cwbvh/ray.h"

namespace cwbvh::test {

struct Box3 {
    float lo[3] = {INFINITY, INFINITY, INFINITY};
    float hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    void grow(const float* v) {
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], v[a]);
            hi[a] = std::max(hi[a], v[a]);
        }
    }
    void grow(const Box3& b) {
        grow(b.lo);
        grow(b.hi);
    }
};

inline Box3 tri_box(const TriangleRecord& t) {
    Box3 b;
    b.grow(t.v0);
    b.grow(t.v1);
    b.grow(t.v2);
    return b;
}

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

struct WideBvh {
    std::vector<CwbvhNode> nodes;
    std::vector<TriangleRecord> tris;
    int depth = 0;
};

/// Conservative quantization of one axis for the given child intervals. Returns the
/// biased exponent; q_lo/q_hi decode to planes with lo <= child lo and hi >= child hi.
inline uint8_t quantize_axis(float p, const std::vector<std::pair<float, float>>& child, uint8_t* qlo,
                             uint8_t* qhi) {
    double ext = 0;
    for (const auto& c : child) ext = std::max(ext, double(c.second) - double(p));
    int e = 1;
    if (ext > 0) e = std::max(1, std::ilogb(ext / 255.0) + 127);
    for (;; ++e) {
        const double s = std::ldexp(1.0, e - 127);
        bool ok = true;
        for (size_t i = 0; i < child.size() && ok; ++i) {
            double fl = std::floor((double(child[i].first) - p) / s);
            int lo = int(std::clamp(fl, 0.0, 255.0));
            while (lo > 0 && decode_plane(p, uint8_t(e), uint8_t(lo)) > child[i].first) --lo;
            double ch = std::ceil((double(child[i].second) - p) / s);
            if (ch > 255.0) {
                ok = false;
                break;
            }
            int hi = int(std::max(ch, 0.0));
            while (hi <= 255 && decode_plane(p, uint8_t(e), uint8_t(hi)) < child[i].second) ++hi;
            if (hi > 255) {
                ok = false;
                break;
            }
            qlo[i] = uint8_t(lo);
            qhi[i] = uint8_t(hi);
        }
        if (ok) return uint8_t(e);
    }
}

/// Build a valid wide tree over `input` (TRIS is a reordered copy, prim kept).
inline WideBvh build_wide(const std::vector<TriangleRecord>& input) {
    WideBvh out;
    struct Pending {
        uint32_t node;
        std::vector<uint32_t> prims;
        int depth;
    };
    std::vector<Box3> boxes(input.size());
    std::vector<float> cent(input.size() * 3);
    for (size_t i = 0; i < input.size(); ++i) {
        boxes[i] = tri_box(input[i]);
        for (int a = 0; a < 3; ++a) cent[i * 3 + a] = 0.5f * boxes[i].lo[a] + 0.5f * boxes[i].hi[a];
    }
    std::vector<Pending> work;
    std::vector<uint32_t> all(input.size());
    std::iota(all.begin(), all.end(), 0u);
    out.nodes.push_back(CwbvhNode{});
    work.push_back({0, all, 1});
    while (!work.empty()) {
        Pending job = std::move(work.back());
        work.pop_back();
        out.depth = std::max(out.depth, job.depth);
        // Split into up to 8 groups: repeatedly median-split the largest group (> 3).
        std::vector<std::vector<uint32_t>> groups{job.prims};
        while (groups.size() < 8) {
            size_t big = 0;
            for (size_t g = 1; g < groups.size(); ++g)
                if (groups[g].size() > groups[big].size()) big = g;
            if (groups[big].size() <= 3 && !(groups.size() == 1 && job.node == 0 && groups[0].size() > 1)) break;
            if (groups[big].size() <= 1) break;
            std::vector<uint32_t>& g = groups[big];
            Box3 cb;
            for (uint32_t p : g) cb.grow(&cent[p * 3]);
            int axis = 0;
            for (int a = 1; a < 3; ++a)
                if (cb.hi[a] - cb.lo[a] > cb.hi[axis] - cb.lo[axis]) axis = a;
            const size_t mid = g.size() / 2;
            std::nth_element(g.begin(), g.begin() + mid, g.end(), [&](uint32_t x, uint32_t y) {
                return cent[x * 3 + axis] < cent[y * 3 + axis] || (cent[x * 3 + axis] == cent[y * 3 + axis] && x < y);
            });
            std::vector<uint32_t> right(g.begin() + mid, g.end());
            g.resize(mid);
            groups.push_back(std::move(right));
        }
        const int nc = int(groups.size());
        std::vector<Box3> cbox(nc);
        Box3 nbox;
        for (int c = 0; c < nc; ++c) {
            for (uint32_t p : groups[c]) cbox[c].grow(boxes[p]);
            nbox.grow(cbox[c]);
        }
        // Greedy octant slot assignment (Ylitie et al. 2017, 3.2; auction replaced by
        // greedy): cost(c, s) = (centroid(c) - centroid(node)) . ds, ds = -1 on the
        // axes whose octant bit is set (bit 2 = x<0, 1 = y<0, 0 = z<0).
        std::vector<int> slot_of(nc, -1);
        std::vector<bool> slot_used(8, false);
        for (int k = 0; k < nc; ++k) {
            double best = INFINITY;
            int bc = -1, bs = -1;
            for (int c = 0; c < nc; ++c) {
                if (slot_of[c] >= 0) continue;
                for (int s = 0; s < 8; ++s) {
                    if (slot_used[s]) continue;
                    double cost = 0;
                    for (int a = 0; a < 3; ++a) {
                        const double d = (double(cbox[c].lo[a]) + cbox[c].hi[a]) - (double(nbox.lo[a]) + nbox.hi[a]);
                        cost += ((s >> (2 - a)) & 1) ? -d : d;
                    }
                    if (cost < best) {
                        best = cost;
                        bc = c;
                        bs = s;
                    }
                }
            }
            slot_of[bc] = bs;
            slot_used[bs] = true;
        }
        std::vector<int> child_in_slot(8, -1);
        for (int c = 0; c < nc; ++c) child_in_slot[slot_of[c]] = c;

        CwbvhNode n{};
        for (int a = 0; a < 3; ++a) {
            n.p[a] = nbox.lo[a];
            std::vector<std::pair<float, float>> iv;
            for (int s = 0; s < 8; ++s)
                if (child_in_slot[s] >= 0) iv.push_back({cbox[child_in_slot[s]].lo[a], cbox[child_in_slot[s]].hi[a]});
            uint8_t qlo[8] = {}, qhi[8] = {};
            n.e[a] = quantize_axis(n.p[a], iv, qlo, qhi);
            int k = 0;
            for (int s = 0; s < 8; ++s)
                if (child_in_slot[s] >= 0) {
                    n.q_lo[a][s] = qlo[k];
                    n.q_hi[a][s] = qhi[k];
                    ++k;
                }
        }
        n.child_base = uint32_t(out.nodes.size());
        n.tri_base = uint32_t(out.tris.size());
        int tri_off = 0;
        std::vector<Pending> kids;
        for (int s = 0; s < 8; ++s) {
            const int c = child_in_slot[s];
            if (c < 0) continue;
            if (groups[c].size() <= 3) {
                n.meta[s] = make_meta_leaf(int(groups[c].size()), tri_off);
                for (uint32_t p : groups[c]) out.tris.push_back(input[p]);
                tri_off += int(groups[c].size());
            } else {
                n.imask |= uint8_t(1u << s);
                n.meta[s] = make_meta_internal(s);
                const uint32_t idx = uint32_t(out.nodes.size());
                out.nodes.push_back(CwbvhNode{});
                kids.push_back({idx, groups[c], job.depth + 1});
            }
        }
        out.nodes[job.node] = n;
        for (auto& k : kids) work.push_back(std::move(k));
    }
    return out;
}

struct Bvh2 {
    std::vector<Bvh2Node> nodes;
    int depth = 0;
};

/// Median-split binary tree with one triangle per leaf over `tris` (leaf = ~index).
inline Bvh2 build_bvh2(const std::vector<TriangleRecord>& tris) {
    Bvh2 out;
    std::vector<uint32_t> idx(tris.size());
    std::iota(idx.begin(), idx.end(), 0u);
    struct Rec {
        static int32_t build(Bvh2& o, const std::vector<TriangleRecord>& t, uint32_t* b, uint32_t* e, int depth, Box3& box) {
            o.depth = std::max(o.depth, depth);
            if (e - b == 1) {
                box = tri_box(t[*b]);
                return ~int32_t(*b);
            }
            Box3 cb;
            for (uint32_t* p = b; p != e; ++p) {
                const Box3 tb = tri_box(t[*p]);
                float c[3];
                for (int a = 0; a < 3; ++a) c[a] = 0.5f * tb.lo[a] + 0.5f * tb.hi[a];
                cb.grow(c);
            }
            int axis = 0;
            for (int a = 1; a < 3; ++a)
                if (cb.hi[a] - cb.lo[a] > cb.hi[axis] - cb.lo[axis]) axis = a;
            uint32_t* mid = b + (e - b) / 2;
            std::nth_element(b, mid, e, [&](uint32_t x, uint32_t y) {
                const Box3 bx = tri_box(t[x]), by = tri_box(t[y]);
                const float cx = bx.lo[axis] + bx.hi[axis], cy = by.lo[axis] + by.hi[axis];
                return cx < cy || (cx == cy && x < y);
            });
            const int32_t me = int32_t(o.nodes.size());
            o.nodes.push_back(Bvh2Node{});
            Box3 b0, b1;
            const int32_t c0 = build(o, t, b, mid, depth + 1, b0);
            const int32_t c1 = build(o, t, mid, e, depth + 1, b1);
            Bvh2Node& n = o.nodes[me];
            n.c0_lo_x = b0.lo[0]; n.c0_hi_x = b0.hi[0]; n.c0_lo_y = b0.lo[1]; n.c0_hi_y = b0.hi[1];
            n.c0_lo_z = b0.lo[2]; n.c0_hi_z = b0.hi[2];
            n.c1_lo_x = b1.lo[0]; n.c1_hi_x = b1.hi[0]; n.c1_lo_y = b1.lo[1]; n.c1_hi_y = b1.hi[1];
            n.c1_lo_z = b1.lo[2]; n.c1_hi_z = b1.hi[2];
            n.child[0] = c0;
            n.child[1] = c1;
            box = b0;
            box.grow(b1);
            return me;
        }
    };
    Box3 root;
    Rec::build(out, tris, idx.data(), idx.data() + idx.size(), 1, root);
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
