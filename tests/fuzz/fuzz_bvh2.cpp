// libFuzzer target for the binary BVH sections (BV2L and BVH2): rules 5601-5610 and the deep
// checks D5-D6. The fuzzed bytes are XORed onto a valid BV2L (or BVH2) tree over a small fixed
// scene, so the empty input is a valid file and small inputs are small corruptions of one;
// bytes past the tree append whole nodes. The first byte's low bit picks BVH2 instead of BV2L.
// A file that passes validate() must pass through the deep checks without a crash.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

#include "cwbvh/format/deep_check.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/scene_data.h"
#include "cwbvh/format/validate.h"
#include "cwbvh/format/writer.h"

namespace {

using namespace cwbvh;

constexpr int kTriangles = 5;

/// One root node with five one-triangle leaves; triangle k spans [k, k+1] on x, [0, 1] on y, z.
SceneData base_scene() {
    SceneData s;
    CwbvhNode root{};
    root.e[0] = root.e[1] = root.e[2] = 127;  // scale 1: a plane byte is a coordinate
    for (int k = 0; k < kTriangles; ++k) {
        root.meta[k] = make_meta_leaf(1, k);
        root.q_lo[0][k] = uint8_t(k);
        root.q_hi[0][k] = uint8_t(k + 1);
        root.q_hi[1][k] = root.q_hi[2][k] = 1;
        TriangleRecord t{};
        t.v0[0] = float(k);
        t.v1[0] = float(k + 1);
        t.v2[0] = float(k);
        t.v2[1] = 1;
        t.v1[2] = 1;
        t.prim = uint32_t(k);
        s.triangles.push_back(t);
    }
    s.nodes.push_back(root);
    s.source_ranges.push_back(SourceRange{0, kTriangles, 0, 0, 0, 0});
    s.bounds = SceneBounds{{0, 0, 0}, {float(kTriangles), 1, 1}};
    return s;
}

void set_box(Bvh2Node& n, int c, float x0, float x1) {
    float* f = c == 0 ? &n.c0_lo_x : &n.c1_lo_x;
    f[0] = x0, f[1] = x1, f[2] = 0, f[3] = 1;
    (c == 0 ? n.c0_lo_z : n.c1_lo_z) = 0;
    (c == 0 ? n.c0_hi_z : n.c1_hi_z) = 1;
}

/// BV2L: the root's child 0 is node 1, child 1 the leaf of records 3-4; node 1 holds the leaves
/// of records 0-1 and 2. BVH2 (one record per leaf): a chain, node i holding record i.
std::vector<Bvh2Node> base_tree(bool leaf_ranges) {
    std::vector<Bvh2Node> t;
    if (leaf_ranges) {
        t.resize(2);
        set_box(t[0], 0, 0, 3), t[0].child[0] = 1;
        set_box(t[0], 1, 3, 5), t[0].child[1] = ~3, t[0].leaf_count[1] = 2;
        set_box(t[1], 0, 0, 2), t[1].child[0] = ~0, t[1].leaf_count[0] = 2;
        set_box(t[1], 1, 2, 3), t[1].child[1] = ~2, t[1].leaf_count[1] = 1;
    } else {
        // A right-leaning chain: node i holds triangle i in child 0 and node i+1 in child 1.
        t.resize(kTriangles - 1);
        for (int i = 0; i < kTriangles - 1; ++i) {
            set_box(t[i], 0, float(i), float(i + 1)), t[i].child[0] = ~i;
            set_box(t[i], 1, float(i + 1), float(kTriangles));
            t[i].child[1] = i + 1 < kTriangles - 1 ? i + 1 : ~(i + 1);
        }
    }
    return t;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const bool leaf_ranges = size == 0 || (data[0] & 1) == 0;
    SceneData s = base_scene();
    s.bvh2 = base_tree(leaf_ranges);
    s.bvh2_leaf_ranges = leaf_ranges;
    const size_t base_bytes = s.bvh2.size() * sizeof(Bvh2Node);
    const size_t body = size > 1 ? size - 1 : 0;
    const size_t nodes = (std::max(base_bytes, body) + sizeof(Bvh2Node) - 1) / sizeof(Bvh2Node);
    std::vector<uint8_t> bytes(std::min<size_t>(nodes, 4096) * sizeof(Bvh2Node), 0);
    std::memcpy(bytes.data(), s.bvh2.data(), base_bytes);
    for (size_t i = 0; i < body && i < bytes.size(); ++i) bytes[i] ^= data[1 + i];
    s.bvh2.resize(bytes.size() / sizeof(Bvh2Node));
    std::memcpy(s.bvh2.data(), bytes.data(), bytes.size());

    Writer w;
    add_scene_sections(w, s);
    std::vector<uint8_t> file;
    if (!w.to_bytes(file).ok()) return 0;
    FileLayout layout;
    const bool valid = validate(file, {}, &layout).ok();
    // The base files (no fuzzed body) are valid and deep-valid, or this harness is broken.
    if (body == 0 && (!valid || !deep_check(s.nodes, s.triangles, kTriangles).ok() ||
                      !deep_check_bvh2(s.bvh2, leaf_ranges, s.triangles, kTriangles).ok()))
        __builtin_trap();
    if (!valid) return 0;
    // Valid: the deep checks must run to an answer (they may still find the geometry wrong).
    (void)deep_check(s.nodes, s.triangles, kTriangles);
    (void)deep_check_bvh2(s.bvh2, leaf_ranges, s.triangles, kTriangles);
    return 0;
}
