// A study, not product code (README.md beside it): node visits and triangle tests per ray
// of four traversal orders over the same compiled file and rays, closest hit, watertight
// triangle test, on the CPU:
//   kernel: traverse_cwbvh itself (the paper's groups in octant order, no distances on
//           the stack: a node's hit leaves are tested at once, a popped group is not culled);
//   groups + pop cull: the same, with the exact entry distance of a pushed node group's
//           remaining children kept beside it and the group skipped on pop when it lies
//           beyond the closest hit (a re-pushed popped group keeps its bound);
//   per child, octant order: every hit child (inner node or leaf) is its own stack entry
//           with its entry distance, in the kernel's octant order, culled on pop;
//   per child, sorted: the same, nearest entry first.
// Child entry distances: the decoded (quantized) child box, slabs in double.
// Build (from the repository root, after a Release build in build/):
//   g++ -std=c++20 -O2 -Ikernels/include -Iformat/include -Iloader/include \
//     bench/results/model/2026-11-27-child-order/order_study.cpp build/lib/libcwbvh_cpu_trace.a \
//     build/lib/libcwbvh_loader.a build/lib/libcwbvh_format.a -lxxhash -o /tmp/order_study
// usage: order_study FILE.cwbvh RAYS
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>
#include "cwbvh/loader/loader.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/kernels/traverse.h"
using namespace cwbvh;

struct Entry { double tn; int kind; uint32_t a, b; };  // kind 0 node (a=index), 1 leaf (a=first tri, b=count)

static bool slab(const CwbvhNode& n, int s, const Ray& r, double tmin, double tmax, double& tn) {
    float lo[3], hi[3];
    decode_slot_box(n, s, lo, hi);
    double t0 = tmin, t1 = tmax;
    for (int a = 0; a < 3; ++a) {
        if (r.dir[a] == 0.0f) { if (r.org[a] < lo[a] || r.org[a] > hi[a]) return false; continue; }
        double inv = 1.0 / double(r.dir[a]);
        double x0 = (double(lo[a]) - r.org[a]) * inv, x1 = (double(hi[a]) - r.org[a]) * inv;
        if (x0 > x1) std::swap(x0, x1);
        t0 = std::max(t0, x0); t1 = std::min(t1, x1);
    }
    tn = t0;
    return t0 <= t1;
}

int main(int argc, char** argv) {
    auto f = File::open(argv[1]);
    if (!f.ok()) { std::fprintf(stderr, "open failed\n"); return 1; }
    std::vector<Ray> rays;
    if (!read_ray_file(argv[2], rays).ok()) { std::fprintf(stderr, "rays failed\n"); return 1; }
    auto nodes = f->nodes(); auto tris = f->triangles();
    double cAn = 0, cAt = 0, c0n = 0, c0t = 0, c1n = 0, c1t = 0, c2n = 0, c2t = 0; size_t diff = 0, n = 0;
    for (const Ray& r : rays) {
        if (!ray_is_traceable(r)) continue;
        ++n;
        Hit h0; LocalStack<64> st; TraceCounters c{};
        traverse_cwbvh<TriangleTest::kWatertight, HitMode::kClosest>(nodes.data(), nodes.size(), tris.data(), tris.size(), r, h0, st, &c);
        c0n += c.nodes; c0t += c.triangles;
        const NodeRay nr = make_node_ray(r);
        {
            const TriangleIntersector<TriangleTest::kWatertight> tt(r);
            float tmax = r.tmax; Hit h = make_miss();
            struct G { uint32_t base, hits; double bound; bool fresh; double bound_slot[8]; };
            std::vector<G> stk;
            G ng{0u, 0x80000000u, 0.0, false, {}}; G tg{0u, 0u, 0.0, false, {}};
            uint32_t vn = 0, vt = 0;
            double tn_slot[8];
            for (;;) {
                if (ng.hits > 0x00FFFFFFu) {
                    const uint32_t hits = ng.hits;
                    const int bit = 31 - __builtin_clz(hits);
                    ng.hits = hits & ~(1u << bit);
                    const uint32_t slot = (uint32_t(bit) & 7u) ^ nr.octinv;
                    const uint32_t idx = ng.base + uint32_t(__builtin_popcount(hits & 0xFFu & ((1u << slot) - 1u)));
                    if (ng.hits > 0x00FFFFFFu) {
                        double b = ng.bound;
                        if (ng.fresh) { b = 1e300; for (int bb = 24; bb < 32; ++bb) if (ng.hits >> bb & 1u) b = std::min(b, ng.bound_slot[(bb & 7) ^ nr.octinv]); }
                        G e = ng; e.bound = b; e.fresh = false;
                        stk.push_back(e);
                    }
                    ++vn;
                    const CwbvhNode& nd = nodes[idx];
                    const uint32_t hm = intersect_node(nd, nr, r.tmin, tmax);
                    for (int s2 = 0; s2 < 8; ++s2) { double tn; tn_slot[s2] = slab(nd, s2, r, r.tmin, 1e300, tn) ? tn : 0.0; }
                    ng = G{nd.child_base, (hm & 0xFF000000u) | nd.imask, 0.0, true, {}};
                    for (int s2 = 0; s2 < 8; ++s2) ng.bound_slot[s2] = tn_slot[s2];
                    tg = G{nd.tri_base, hm & 0x00FFFFFFu, 0.0, false, {}};
                }
                while (tg.hits) {
                    const int bit = 31 - __builtin_clz(tg.hits);
                    tg.hits &= ~(1u << bit);
                    ++vt;
                    cwbvh_triangle_step(tt, tris[tg.base + uint32_t(bit)], r.tmin, tmax, h);
                }
                if (ng.hits <= 0x00FFFFFFu) {
                    bool got = false;
                    while (!stk.empty()) {
                        G e = stk.back(); stk.pop_back();
                        if (e.bound > tmax) continue;
                        ng = e; got = true; break;
                    }
                    if (!got) break;
                }
            }
            cAn += vn; cAt += vt;
            if (h.t != h0.t) ++diff;
        }
        const TriangleIntersector<TriangleTest::kWatertight> tt(r);
        for (int variant = 1; variant <= 2; ++variant) {
            float tmax = r.tmax; Hit h = make_miss();
            std::vector<Entry> stack{{0.0, 0, 0, 0}};
            uint32_t vn = 0, vt = 0;
            while (!stack.empty()) {
                Entry e = stack.back(); stack.pop_back();
                if (e.tn > tmax) continue;
                if (e.kind == 1) {
                    for (uint32_t i = 0; i < e.b; ++i) { ++vt; cwbvh_triangle_step(tt, tris[e.a + i], r.tmin, tmax, h); }
                    continue;
                }
                ++vn;
                const CwbvhNode& nd = nodes[e.a];
                std::vector<Entry> kids;
                for (int b = 7; b >= 0; --b) {
                    const int s = b ^ int(nr.octinv);
                    const uint8_t m = nd.meta[s];
                    if (meta_is_empty(m)) continue;
                    double tn;
                    if (!slab(nd, s, r, r.tmin, tmax, tn)) continue;
                    if (meta_is_internal(m)) kids.push_back({tn, 0, internal_child_index(nd, s), 0});
                    else kids.push_back({tn, 1, nd.tri_base + uint32_t(meta_leaf_offset(m)), uint32_t(meta_leaf_count(m))});
                }
                if (variant == 2) std::stable_sort(kids.begin(), kids.end(), [](const Entry& x, const Entry& y) { return x.tn < y.tn; });
                for (auto it = kids.rbegin(); it != kids.rend(); ++it) stack.push_back(*it);
            }
            if (variant == 1) { c1n += vn; c1t += vt; } else { c2n += vn; c2t += vt; }
            if (h.t != h0.t) ++diff;
        }
    }
    std::printf("rays %zu | kernel order (groups): nodes %.2f tris %.2f | groups + pop cull: nodes %.2f tris %.2f | "
                "per child, octant order, pop cull: nodes %.2f tris %.2f | per child, sorted: nodes %.2f tris %.2f | "
                "closest t differs from the kernel order's on %zu ray-variants\n",
                n, c0n / n, c0t / n, cAn / n, cAt / n, c1n / n, c1t / n, c2n / n, c2t / n, diff);
}
