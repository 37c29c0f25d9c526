#include "format/vectors.h"

#include "cwbvh/format/node_decode.h"
#include "format/test_util.h"
#include "format/two_level_scene.h"

namespace cwbvh::test {
namespace {

/// One triangle (0,0,0) (1,0,0) (0,1,0); a root whose slot 0 is a leaf.
/// x, y: extent 1 -> e = 120 (scale 2^-7), q_hi = 128 decodes to exactly 1.
/// z: extent 0 -> e = 1 (the smallest scale), q_lo = q_hi = 0.
SceneData single_triangle() {
    SceneData s;
    CwbvhNode root{};
    root.e[0] = root.e[1] = 120;
    root.e[2] = 1;
    root.meta[0] = make_meta_leaf(1, 0);
    root.q_hi[0][0] = 128;
    root.q_hi[1][0] = 128;
    s.nodes.push_back(root);
    s.triangles.push_back(TriangleRecord{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, 0});
    s.source_ranges.push_back(SourceRange{0, 1, 0, 0, 0, 0});
    s.bounds = SceneBounds{{0, 0, 0}, {1, 1, 0}};
    s.bvh2.push_back(Bvh2Node{0, 1, 0, 1, 0, 1, 0, 1, 0, 0, 0, 0, {~0, ~0}, {0, 0}});
    s.vertices = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    s.indices = {0, 1, 2};
    s.source_names = std::string("triangle.obj") + '\0';
    BuildInfo b{};
    b.builder = kBuilderSbvh;
    b.collapse = kCollapseOptimal;
    b.split_alpha = 1e-5f;
    b.cost_node = 1.0f;
    b.cost_prim = 0.3f;
    b.max_leaf_triangles = 3;
    b.input_triangles = b.triangles = b.references = 1;
    b.binary_nodes = 1;
    b.wide_nodes = 1;
    b.sah_binary = 0.3;  // one leaf with one triangle: C_prim * 1 * A/A
    b.sah_wide = 1.3;    // the root node (C_node) + its leaf
    b.avg_children = 1;
    s.build_info = b;
    return s;
}

}  // namespace

std::vector<Vector> make_vectors() {
    std::vector<Vector> v;
    const SceneData one = single_triangle();
    v.push_back({"single_triangle", file_bytes(one)});

    SyntheticOptions o;
    o.triangles = 30;
    const SceneData small = make_synthetic_scene(o);
    v.push_back({"internal_children", file_bytes(small)});

    // Format 1.1: the binary BVH as BV2L, leaves of up to 3 consecutive records.
    SyntheticOptions lr;
    lr.triangles = 10;
    lr.source_geometry = false;
    lr.bvh2_leaf_ranges = true;
    const SceneData ranges = make_synthetic_scene(lr);
    v.push_back({"leaf_ranges", file_bytes(ranges)});
    {  // the root's first leaf child reaches one record past the end of TRIS
        std::vector<uint8_t> f = file_bytes(ranges);
        const uint32_t tris = uint32_t(ranges.triangles.size());
        uint64_t node = 0;
        int child = -1;
        for (uint64_t i = 0; i < ranges.bvh2.size() && child < 0; ++i)
            for (int c = 0; c < 2 && child < 0; ++c)
                if (ranges.bvh2[i].child[c] < 0) node = i, child = c;
        edit_element<Bvh2Node>(f, kSectionBvh2Leaves, node, [&](Bvh2Node& n) {
            n.child[child] = ~int32_t(tris - 1);
            n.leaf_count[child] = 2;
        });
        v.push_back({"invalid_5608_leaf_range", f});
    }
    {  // root child_base points at the root itself
        std::vector<uint8_t> f = file_bytes(small);
        edit_element<CwbvhNode>(f, kSectionNodes, 0, [](CwbvhNode& n) { n.child_base = 0; });
        v.push_back({"invalid_5105_child_order", f});
    }
    // Format 1.2: a two-level scene (two meshes, five instances, a two-level TLAS).
    const SceneData instanced = standard_two_level();
    v.push_back({"instanced", file_bytes(instanced)});
    {  // instance 1's object_to_world flattened to the plane z = 0: singular
        std::vector<uint8_t> f = file_bytes(instanced);
        edit_element<InstanceRecord>(f, kSectionInstances, 1, [](InstanceRecord& r) { r.object_to_world[2][2] = 0; });
        v.push_back({"invalid_6022_singular_transform", f});
    }
    {  // the TLAS's second node takes instance 1, which the root's leaf holds already
        std::vector<uint8_t> f = file_bytes(instanced);
        edit_element<CwbvhNode>(f, kSectionTopNodes, 1, [](CwbvhNode& n) { n.tri_base = 1; });
        v.push_back({"invalid_6109_instance_twice", f});
    }
    {  // a future major version
        std::vector<uint8_t> f = file_bytes(one);
        FileHeader h = header_of(f);
        h.version_major = 2;
        set_header(f, h);
        reseal(f);
        v.push_back({"invalid_2003_major_version", f});
    }
    {  // truncated by 100 bytes
        std::vector<uint8_t> f = file_bytes(one);
        f.resize(f.size() - 100);
        v.push_back({"invalid_3002_truncated", f});
    }
    return v;
}

}  // namespace cwbvh::test
