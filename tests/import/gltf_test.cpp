// glTF 2.0 through the tinygltf adapter: generated files (JSON + base64
// buffer) for each feature, the assimp malformed samples, Draco, real scenes.
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <limits>

#include "import/import_test_util.h"
#include "scene_corpus.h"

namespace cwbvh::compiler::test {
namespace {

std::string base64(const std::string& in) {
    static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    size_t i = 0;
    for (; i + 2 < in.size(); i += 3) {
        const uint32_t v = (uint32_t(uint8_t(in[i])) << 16) | (uint32_t(uint8_t(in[i + 1])) << 8) |
                           uint8_t(in[i + 2]);
        for (int s = 18; s >= 0; s -= 6) out.push_back(k[(v >> s) & 63]);
    }
    if (i < in.size()) {
        uint32_t v = uint32_t(uint8_t(in[i])) << 16;
        if (i + 1 < in.size()) v |= uint32_t(uint8_t(in[i + 1])) << 8;
        out.push_back(k[(v >> 18) & 63]);
        out.push_back(k[(v >> 12) & 63]);
        out.push_back(i + 1 < in.size() ? k[(v >> 6) & 63] : '=');
        out.push_back('=');
    }
    return out;
}

/// Builds a glTF file: one buffer (base64 data URI), one bufferView per
/// accessor unless told otherwise.
class GltfBuilder {
public:
    /// Appends raw bytes (4-aligned) as a new bufferView; returns its index.
    int view(const std::string& bytes, int stride = 0) {
        while (bin_.size() % 4) bin_.push_back('\0');
        add(views_, "{\"buffer\":0,\"byteOffset\":" + std::to_string(bin_.size()) +
                        ",\"byteLength\":" + std::to_string(bytes.size()) +
                        (stride ? ",\"byteStride\":" + std::to_string(stride) : "") + "}");
        bin_ += bytes;
        return nviews_++;
    }
    int accessor(const std::string& json) {
        add(accessors_, json);
        return naccessors_++;
    }
    int positions(const std::vector<Vec3>& v) {
        std::string b(reinterpret_cast<const char*>(v.data()), v.size() * 12);
        return accessor("{\"bufferView\":" + std::to_string(view(b)) +
                        ",\"componentType\":5126,\"type\":\"VEC3\",\"count\":" +
                        std::to_string(v.size()) + "}");
    }
    template <class T>
    int indices(const std::vector<T>& idx) {
        std::string b(reinterpret_cast<const char*>(idx.data()), idx.size() * sizeof(T));
        const int ct = sizeof(T) == 1 ? 5121 : sizeof(T) == 2 ? 5123 : 5125;
        return accessor("{\"bufferView\":" + std::to_string(view(b)) +
                        ",\"componentType\":" + std::to_string(ct) +
                        ",\"type\":\"SCALAR\",\"count\":" + std::to_string(idx.size()) + "}");
    }
    /// A mesh from primitive JSON objects; returns its index.
    int mesh(const std::vector<std::string>& prims) {
        std::string j = "{\"primitives\":[";
        for (size_t i = 0; i < prims.size(); ++i) j += (i ? "," : "") + prims[i];
        add(meshes_, j + "]}");
        return nmeshes_++;
    }
    int node(const std::string& json) {
        add(nodes_, json);
        return nnodes_++;
    }
    std::string extra_top;  ///< e.g. ",\"extensionsUsed\":[...]"
    std::string scenes;     ///< e.g. "\"scenes\":[{\"nodes\":[0]}],\"scene\":0,"
    std::string json() const {
        const std::string bin = bin_.empty() ? std::string(4, '\0') : bin_;
        return "{\"asset\":{\"version\":\"2.0\"}," + scenes +
               "\"buffers\":[{\"byteLength\":" + std::to_string(bin.size()) +
               ",\"uri\":\"data:application/octet-stream;base64," + base64(bin) + "\"}]," +
               "\"bufferViews\":[" + views_ + "],\"accessors\":[" + accessors_ +
               "],\"meshes\":[" + meshes_ + "],\"nodes\":[" + nodes_ + "]" + extra_top + "}";
    }

private:
    static void add(std::string& list, const std::string& item) {
        if (!list.empty()) list += ",";
        list += item;
    }
    std::string bin_, views_, accessors_, meshes_, nodes_;
    int nviews_ = 0, naccessors_ = 0, nmeshes_ = 0, nnodes_ = 0;
};

std::string prim(int pos, int idx = -1, int mode = 4) {
    return "{\"attributes\":{\"POSITION\":" + std::to_string(pos) + "}" +
           (idx >= 0 ? ",\"indices\":" + std::to_string(idx) : "") +
           ",\"mode\":" + std::to_string(mode) + "}";
}

const std::vector<Vec3> kSquare = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5f, 2, 0}};

Result load(const TempDir& dir, const GltfBuilder& b, bool permissive = false) {
    return import_files({dir.write("t.gltf", b.json())}, permissive);
}

using Tri = std::array<uint32_t, 3>;

TEST(Gltf, IndexTypesAndNoIndices) {
    TempDir dir;
    GltfBuilder b;
    const int pos = b.positions(kSquare);
    b.mesh({prim(pos, b.indices<uint8_t>({0, 1, 2})), prim(pos, b.indices<uint16_t>({0, 2, 3})),
            prim(pos, b.indices<uint32_t>({3, 2, 4})), prim(b.positions({{0, 0, 1}, {1, 0, 1}, {0, 1, 1}}))});
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    const Scene& s = r.scene;
    ASSERT_EQ(s.triangle_count(), 4u);
    EXPECT_EQ(s.triangle(0)[2], (Vec3{1, 1, 0}));
    EXPECT_EQ(s.triangle(1)[2], (Vec3{0, 1, 0}));
    EXPECT_EQ(s.triangle(2)[2], (Vec3{0.5f, 2, 0}));
    EXPECT_EQ(s.triangle(3)[0], (Vec3{0, 0, 1}));
    for (uint32_t i = 0; i < 4; ++i) {
        EXPECT_EQ(s.sources[i].mesh, 0u);
        EXPECT_EQ(s.sources[i].primitive, i);
        EXPECT_EQ(s.sources[i].triangle, 0u);
    }
}

TEST(Gltf, StripAlternatesWindingAndFanFollowsTheSpec) {
    TempDir dir;
    GltfBuilder b;
    const int pos = b.positions(kSquare);
    // Strip 0 1 3 2 4: (0,1,3) (3,1,2)... spec: p_i = {v_i, v_{i+1+i%2}, v_{i+2-i%2}}.
    b.mesh({prim(pos, b.indices<uint16_t>({0, 1, 3, 2, 4}), 5),
            prim(pos, b.indices<uint16_t>({0, 1, 2, 4}), 6)});
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    const Scene& s = r.scene;
    ASSERT_EQ(s.triangle_count(), 5u);
    auto pos_of = [&](size_t t) {
        std::array<Vec3, 3> v = s.triangle(t);
        return v;
    };
    auto expect_tri = [&](size_t t, int a, int bb, int c) {
        EXPECT_EQ(pos_of(t)[0], kSquare[size_t(a)]) << t;
        EXPECT_EQ(pos_of(t)[1], kSquare[size_t(bb)]) << t;
        EXPECT_EQ(pos_of(t)[2], kSquare[size_t(c)]) << t;
    };
    expect_tri(0, 0, 1, 3);
    expect_tri(1, 1, 2, 3);  // i=1: {v1, v3, v2} = {1, 2, 3}
    expect_tri(2, 3, 2, 4);  // i=2: {v2, v3, v4} = {3, 2, 4}
    expect_tri(3, 1, 2, 0);  // fan i=0: {v1, v2, v0}
    expect_tri(4, 2, 4, 0);  // fan i=1: {v2, v3, v0}
    EXPECT_EQ(s.sources[2].triangle, 2u);
    EXPECT_EQ(s.sources[4].primitive, 1u);
    EXPECT_EQ(s.sources[4].triangle, 1u);
}

TEST(Gltf, PointsAndLinesAreSkippedAndCounted) {
    TempDir dir;
    GltfBuilder b;
    const int pos = b.positions(kSquare);
    b.mesh({prim(pos, -1, 0), prim(pos, -1, 1), prim(pos, -1, 2), prim(pos, -1, 3),
            prim(pos, b.indices<uint8_t>({0, 1, 2}))});
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scene.triangle_count(), 1u);
    EXPECT_EQ(r.scene.sources[0].primitive, 4u);
    EXPECT_EQ(r.scene.skipped_primitives.at("points"), 1u);
    EXPECT_EQ(r.scene.skipped_primitives.at("lines"), 1u);
    EXPECT_EQ(r.scene.skipped_primitives.at("line_loop"), 1u);
    EXPECT_EQ(r.scene.skipped_primitives.at("line_strip"), 1u);
}

TEST(Gltf, NodeHierarchyWithTrsAndMatrixIsBaked) {
    TempDir dir;
    GltfBuilder b;
    const int pos = b.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
    b.mesh({prim(pos)});
    // node 0: translate (10,0,0), child node 1: rotate 90 deg about Z then
    // scale 2, child node 2: matrix translating (0,0,5), mesh 0.
    const double h = std::sqrt(0.5);
    b.node("{\"translation\":[10,0,0],\"children\":[1]}");
    b.node("{\"rotation\":[0,0," + std::to_string(h) + "," + std::to_string(h) +
           "],\"scale\":[2,2,2],\"children\":[2]}");
    b.node("{\"matrix\":[1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1],\"mesh\":0}");
    b.node("{\"mesh\":0}");  // not in the scene: ignored
    b.scenes = "\"scenes\":[{\"nodes\":[3]},{\"nodes\":[0]}],\"scene\":1,";
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.scene.triangle_count(), 1u);
    // world = T(10,0,0) * Rz90 * S2 * T(0,0,5): p -> (10 - 2y, 2x, 2(z+5)).
    const auto t = r.scene.triangle(0);
    const std::array<Vec3, 3> expect = {Vec3{10, 2, 10}, Vec3{8, 0, 10}, Vec3{10, 0, 12}};
    for (int k = 0; k < 3; ++k)
        for (int a = 0; a < 3; ++a) EXPECT_NEAR(t[size_t(k)][size_t(a)], expect[size_t(k)][size_t(a)], 1e-6);
}

TEST(Gltf, InstancedMeshAppearsPerNodeAndNoSceneMeansEachMeshOnce) {
    TempDir dir;
    GltfBuilder b;
    b.mesh({prim(b.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}))});
    b.node("{\"mesh\":0}");
    b.node("{\"mesh\":0,\"translation\":[0,0,3]}");
    b.scenes = "\"scenes\":[{\"nodes\":[0,1]}],";
    auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.scene.triangle_count(), 2u);
    EXPECT_EQ(r.scene.sources[1].mesh, 0u);
    // Both instances have the mesh's triangle (the second node takes the
    // cached triangles, the first gets a copy).
    EXPECT_EQ(r.scene.triangle(0)[0], (Vec3{1, 0, 0}));
    EXPECT_EQ(r.scene.triangle(1)[0], (Vec3{1, 0, 3}));
    EXPECT_EQ(r.scene.triangle(1)[2], (Vec3{0, 0, 4}));
    b.scenes.clear();
    r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scene.triangle_count(), 1u);
}

TEST(Gltf, RecursiveNodesAndSharedChildrenAreRejected) {
    TempDir dir;
    GltfBuilder b;
    b.mesh({prim(b.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}))});
    b.node("{\"children\":[1]}");
    b.node("{\"children\":[0],\"mesh\":0}");
    b.scenes = "\"scenes\":[{\"nodes\":[0]}],";
    auto r = load(dir, b);
    ASSERT_FALSE(r.ok);
    EXPECT_NE(r.error.find("recursive"), std::string::npos) << r.error;

    GltfBuilder c;
    c.mesh({prim(c.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}))});
    c.node("{\"children\":[2]}");
    c.node("{\"children\":[2]}");
    c.node("{\"mesh\":0}");
    c.scenes = "\"scenes\":[{\"nodes\":[0,1]}],";
    r = load(dir, c);
    ASSERT_FALSE(r.ok);
    EXPECT_NE(r.error.find("more than one parent"), std::string::npos) << r.error;
    r = load(dir, c, /*permissive=*/true);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.scene.triangle_count(), 2u);
    // One node naming the mesh, emitted twice: the second emission gets the
    // same triangle (the importer hands the cached triangles to the node it
    // counted last and decodes again for an instance it did not count).
    EXPECT_EQ(r.scene.triangle(0), r.scene.triangle(1));
    EXPECT_EQ(r.scene.triangle(1)[2], (Vec3{0, 0, 1}));
}

TEST(Gltf, DeepNodeChainDoesNotOverflowTheStack) {
    TempDir dir;
    GltfBuilder b;
    b.mesh({prim(b.positions({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}))});
    const int depth = 100000;
    for (int i = 0; i < depth - 1; ++i) b.node("{\"children\":[" + std::to_string(i + 1) + "]}");
    b.node("{\"mesh\":0}");
    b.scenes = "\"scenes\":[{\"nodes\":[0]}],";
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scene.triangle_count(), 1u);
}

TEST(Gltf, SparseAccessorIsApplied) {
    TempDir dir;
    GltfBuilder b;
    const std::vector<Vec3> base = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    const int bv = b.view(std::string(reinterpret_cast<const char*>(base.data()), 36));
    const uint16_t sidx[1] = {2};
    const float sval[3] = {0, 7, 0};
    const int iv = b.view(std::string(reinterpret_cast<const char*>(sidx), 2));
    const int vv = b.view(std::string(reinterpret_cast<const char*>(sval), 12));
    const std::string sparse = ",\"sparse\":{\"count\":1,\"indices\":{\"bufferView\":" +
                               std::to_string(iv) + ",\"componentType\":5123},\"values\":{\"bufferView\":" +
                               std::to_string(vv) + "}}";
    const int a = b.accessor("{\"bufferView\":" + std::to_string(bv) +
                             ",\"componentType\":5126,\"type\":\"VEC3\",\"count\":3" + sparse + "}");
    // An accessor without bufferView (zeros) plus sparse values.
    const int z = b.accessor("{\"componentType\":5126,\"type\":\"VEC3\",\"count\":3" + sparse + "}");
    b.mesh({prim(a), prim(z)});
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.scene.triangle_count(), 1u);  // the second is degenerate (0,0,0),(0,0,0),(0,7,0)
    EXPECT_EQ(r.scene.triangle(0)[2], (Vec3{0, 7, 0}));
    EXPECT_EQ(r.scene.dropped.at("degenerate"), 1u);

    // Sparse index out of range.
    GltfBuilder c;
    const uint16_t bad[1] = {3};
    const int bv2 = c.view(std::string(reinterpret_cast<const char*>(base.data()), 36));
    const int iv2 = c.view(std::string(reinterpret_cast<const char*>(bad), 2));
    const int vv2 = c.view(std::string(reinterpret_cast<const char*>(sval), 12));
    const int a2 = c.accessor("{\"bufferView\":" + std::to_string(bv2) +
                              ",\"componentType\":5126,\"type\":\"VEC3\",\"count\":3,\"sparse\":{\"count\":1,\"indices\":{\"bufferView\":" +
                              std::to_string(iv2) + ",\"componentType\":5123},\"values\":{\"bufferView\":" +
                              std::to_string(vv2) + "}}}");
    c.mesh({prim(a2)});
    const auto r2 = load(dir, c);
    ASSERT_FALSE(r2.ok);
    EXPECT_NE(r2.error.find("sparse index 3"), std::string::npos) << r2.error;
}

TEST(Gltf, MeshQuantizationDequantizesPerSpec) {
    TempDir dir;
    GltfBuilder b;
    // int16 normalized: 32767 -> 1, -32768 -> -1 (clamped), 16384 -> 16384/32767.
    const int16_t s16[12] = {32767, 0, 0, 0, 0, -32768, 0, 0, 0, 0, 16384, 0};  // stride 8
    const int bv = b.view(std::string(reinterpret_cast<const char*>(s16), sizeof s16), 8);
    const int a = b.accessor("{\"bufferView\":" + std::to_string(bv) +
                             ",\"componentType\":5122,\"normalized\":true,\"type\":\"VEC3\",\"count\":3}");
    // uint8 unnormalized with a scale node (the usual quantization scheme).
    const uint8_t u8[12] = {10, 0, 0, 0, 0, 20, 0, 0, 0, 0, 30, 0};  // stride 4
    const int bv8 = b.view(std::string(reinterpret_cast<const char*>(u8), sizeof u8), 4);
    const int a8 = b.accessor("{\"bufferView\":" + std::to_string(bv8) +
                              ",\"componentType\":5121,\"type\":\"VEC3\",\"count\":3}");
    b.mesh({prim(a)});
    b.mesh({prim(a8)});
    b.node("{\"mesh\":0}");
    b.node("{\"mesh\":1,\"scale\":[0.5,0.5,0.5]}");
    b.scenes = "\"scenes\":[{\"nodes\":[0,1]}],";
    auto r = load(dir, b);
    ASSERT_FALSE(r.ok);  // integer positions need KHR_mesh_quantization
    EXPECT_NE(r.error.find("KHR_mesh_quantization"), std::string::npos) << r.error;
    b.extra_top = ",\"extensionsUsed\":[\"KHR_mesh_quantization\"],\"extensionsRequired\":[\"KHR_mesh_quantization\"]";
    r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.scene.triangle_count(), 2u);
    const auto t = r.scene.triangle(0);
    EXPECT_EQ(t[0], (Vec3{1, 0, 0}));
    EXPECT_EQ(t[1], (Vec3{0, -1, 0}));
    EXPECT_EQ(t[2][2], float(16384.0 / 32767.0));
    const auto u = r.scene.triangle(1);
    EXPECT_EQ(u[0], (Vec3{5, 0, 0}));
    EXPECT_EQ(u[2], (Vec3{0, 0, 15}));
}

TEST(Gltf, NonfiniteAndDegenerateAreDropped) {
    TempDir dir;
    GltfBuilder b;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const int pos = b.positions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {nan, 0, 0}, {2, 0, 0}});
    b.mesh({prim(pos, b.indices<uint8_t>({0, 1, 2, 0, 1, 3, 0, 1, 4, 1, 1, 2}))});
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scene.input_triangles, 4u);
    EXPECT_EQ(r.scene.triangle_count(), 1u);
    EXPECT_EQ(r.scene.dropped.at("nonfinite"), 1u);
    EXPECT_EQ(r.scene.dropped.at("degenerate"), 2u);
}

TEST(Gltf, BadAccessorsAndIndicesAreRejected) {
    TempDir dir;
    auto expect_error = [&](GltfBuilder& b, const std::string& what) {
        const auto r = load(dir, b);
        EXPECT_FALSE(r.ok) << what;
        EXPECT_NE(r.error.find(what), std::string::npos) << r.error;
        EXPECT_NE(r.error.find("t.gltf"), std::string::npos) << r.error;
    };
    {  // count larger than the bufferView
        GltfBuilder b;
        const int bv = b.view(std::string(36, '\0'));
        b.mesh({prim(b.accessor("{\"bufferView\":" + std::to_string(bv) +
                                ",\"componentType\":5126,\"type\":\"VEC3\",\"count\":4}"))});
        expect_error(b, "overrun");
    }
    {  // byteOffset pushes the last element out
        GltfBuilder b;
        const int bv = b.view(std::string(36, '\0'));
        b.mesh({prim(b.accessor("{\"bufferView\":" + std::to_string(bv) +
                                ",\"byteOffset\":4,\"componentType\":5126,\"type\":\"VEC3\",\"count\":3}"))});
        expect_error(b, "overrun");
    }
    {  // stride too large for the view
        GltfBuilder b;
        const int bv = b.view(std::string(36, '\0'), 16);
        b.mesh({prim(b.accessor("{\"bufferView\":" + std::to_string(bv) +
                                ",\"componentType\":5126,\"type\":\"VEC3\",\"count\":3}"))});
        expect_error(b, "overrun");
    }
    {  // index out of range names mesh and primitive
        GltfBuilder b;
        const int pos = b.positions(kSquare);
        b.mesh({prim(pos, b.indices<uint16_t>({0, 1, 2})), prim(pos, b.indices<uint16_t>({0, 1, 5}))});
        expect_error(b, "mesh 0 primitive 1: index 5 at position 2 is out of range");
    }
    {  // wrong type / component type
        GltfBuilder b;
        const int bv = b.view(std::string(36, '\0'));
        b.mesh({prim(b.accessor("{\"bufferView\":" + std::to_string(bv) +
                                ",\"componentType\":5126,\"type\":\"VEC2\",\"count\":3}"))});
        expect_error(b, "expected VEC3");
    }
    {  // float indices
        GltfBuilder b;
        const int pos = b.positions(kSquare);
        const int bv = b.view(std::string(12, '\0'));
        b.mesh({prim(pos, b.accessor("{\"bufferView\":" + std::to_string(bv) +
                                     ",\"componentType\":5126,\"type\":\"SCALAR\",\"count\":3}"))});
        expect_error(b, "unsupported componentType");
    }
    {  // unsupported required extension
        GltfBuilder b;
        b.mesh({prim(b.positions(kSquare))});
        b.extra_top = ",\"extensionsUsed\":[\"EXT_meshopt_compression\"],\"extensionsRequired\":[\"EXT_meshopt_compression\"]";
        expect_error(b, "required extension EXT_meshopt_compression");
    }
    {  // huge count without bufferView
        GltfBuilder b;
        b.mesh({prim(b.accessor("{\"componentType\":5126,\"type\":\"VEC3\",\"count\":2000000000}"))});
        expect_error(b, "limit");
    }
}

// tinygltf converts `extras` recursively: about 30,000 nested brackets in a 100 KB file
// overflowed its stack (SIGSEGV; hostile-input audit). JSON nesting beyond 512 is refused
// before any parser runs, in .gltf and in a GLB's JSON chunk; brackets inside strings do
// not count, and 512 levels of extras still load.
TEST(Gltf, DeeplyNestedJsonIsAnErrorNotACrash) {
    TempDir dir;
    GltfBuilder b;
    b.mesh({prim(b.positions(kSquare))});
    b.node("{\"mesh\":0}");
    b.scenes = "\"scenes\":[{\"nodes\":[0]}],\"scene\":0,";
    auto nested = [](int d) { return std::string(size_t(d), '[') + std::string(size_t(d), ']'); };
    auto with_extras = [&](const std::string& extras) {
        std::string j = b.json();
        return j.substr(0, j.size() - 1) + ",\"extras\":" + extras + "}";
    };
    const std::string deep = with_extras(nested(50000));
    const std::string p = dir.write("deep.gltf", deep);
    Result r = import_files({p});
    ASSERT_FALSE(r.ok);
    EXPECT_EQ(r.error, p + ": JSON nests arrays or objects more than 512 deep");
    // The same JSON as a GLB's JSON chunk (no BIN chunk: the buffer is a data URI).
    std::string json = deep;
    while (json.size() % 4) json.push_back(' ');
    auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
    const std::string glb = "glTF" + u32(2) + u32(uint32_t(20 + json.size())) + u32(uint32_t(json.size())) +
                            u32(0x4E4F534A) + json;
    const std::string pg = dir.write("deep.glb", glb);
    r = import_files({pg});
    ASSERT_FALSE(r.ok);
    EXPECT_EQ(r.error, pg + ": JSON nests arrays or objects more than 512 deep");
    // At the limit, and with brackets in a string (escaped quotes included), it loads.
    for (const std::string& extras : {nested(511), "{\"a\":\"\\\"" + std::string(2000, '[') + "\"}"}) {
        const Result ok = import_files({dir.write("ok.gltf", with_extras(extras))});
        ASSERT_TRUE(ok.ok) << ok.error;
        EXPECT_EQ(ok.scene.triangle_count(), 1u);
    }
}

// A glTF 1.0 file said "no triangles"; it now says what it is.
TEST(Gltf, Version1IsNamed) {
    TempDir dir;
    for (const char* version : {"1.0", "1.1"}) {
        const std::string p =
            dir.write("v1.gltf", std::string("{\"asset\":{\"version\":\"") + version + "\"},\"meshes\":{},\"nodes\":{}}");
        const Result r = import_files({p});
        ASSERT_FALSE(r.ok);
        EXPECT_NE(r.error.find(": glTF version '"), std::string::npos) << r.error;
        EXPECT_NE(r.error.find("is not supported (glTF 2.0 only)"), std::string::npos) << r.error;
    }
}

TEST(Gltf, NoImageIsEverDecoded) {
    TempDir dir;
    GltfBuilder b;
    b.mesh({prim(b.positions(kSquare))});
    b.extra_top = ",\"images\":[{\"uri\":\"does_not_exist.png\"},{\"uri\":\"data:image/png;base64,AAAA\"}]";
    const auto r = load(dir, b);
    ASSERT_TRUE(r.ok) << r.error;
}

// ---------------------------------------------------------------------------
// Files from the assimp test corpus (Debian package assimp-testmodels).
// ---------------------------------------------------------------------------

const std::string kAssimp = "/usr/share/assimp/models/glTF2/";

std::vector<std::string> files_in(const std::string& dir) {
    std::vector<std::string> out;
    std::error_code ec;
    for (const auto& e : std::filesystem::recursive_directory_iterator(dir, ec)) {
        const std::string p = e.path().string();
        const std::string ext = e.path().extension().string();
        if (e.is_regular_file() && (ext == ".gltf" || ext == ".glb")) out.push_back(p);
    }
    std::sort(out.begin(), out.end());
    return out;
}

/// The verdict on one file of the corpus: loads with `triangles`, or fails with an error
/// that names the file and contains `error`.
struct Verdict {
    const char* file;  ///< under kAssimp
    size_t triangles;  ///< 0: rejected
    const char* error;
};

TEST(GltfAssimp, MalformedFilesGetTheirVerdict) {
    if (!exists(kAssimp)) GTEST_SKIP() << kAssimp << " not installed";
    const Verdict expected[] = {
        // Cube 12 + IndexedCube 12 + the truncated copies' whole triangles 11 + 11 (35 of 36
        // vertices / indices: the trailing partial triangle is dropped); lines are not triangles.
        {"IncorrectVertexArrays/Cube.gltf", 46, nullptr},
        {"IndexOutOfRange/AllIndicesOutOfRange.gltf", 0, "index 65535 at position 0 is out of range (24 vertices)"},
        {"IndexOutOfRange/IndexOutOfRange.gltf", 0, "index 255 at position 0 is out of range (24 vertices)"},
        {"MissingBin/BoxTextured.gltf", 0, "File not found : BoxTextured0.bin"},
        {"RecursiveNodes/RecursiveNodes.gltf", 0, "node 0 is its own ancestor"},
        {"SchemaFailures/sceneWrongType.gltf", 0, "File not found : BoxTextured0.bin"},
        {"TestNoRootNode/NoScene.gltf", 0, "no triangles"},
        {"TestNoRootNode/SceneWithoutNodes.gltf", 0, "no triangles"},
        {"wrongTypes/badArray.gltf", 0, "no triangles"},  // "primitives" is not an array
        // Wrong types in fields the importer does not read (extensions, materials, names).
        {"wrongTypes/badExtension.gltf", 12, nullptr},
        {"wrongTypes/badNumber.gltf", 12, nullptr},
        {"wrongTypes/badObject.gltf", 12, nullptr},
        {"wrongTypes/badString.gltf", 12, nullptr},
        {"wrongTypes/badUint.gltf", 12, nullptr},
        {"BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb", 0, "no triangles (all 12 dropped: 12 nonfinite)"},
        {"BoxBadNormals-glTF-Binary/BoxBadNormals.glb", 12, nullptr},  // normals are not read
    };
    size_t listed = 0;
    for (const char* d : {"IncorrectVertexArrays", "IndexOutOfRange", "MissingBin", "RecursiveNodes",
                          "SchemaFailures", "TestNoRootNode", "wrongTypes", "BoxWithInfinites-glTF-Binary",
                          "BoxBadNormals-glTF-Binary"}) {
        for (const std::string& f : files_in(kAssimp + d)) {
            SCOPED_TRACE(f);
            const auto r = import_files({f});
            std::printf("  %-70s %s\n", f.substr(kAssimp.size()).c_str(),
                        r.ok ? ("ok, " + std::to_string(r.scene.triangle_count()) + " triangles").c_str()
                             : r.error.substr(f.size() + 2).c_str());
            const Verdict* v = nullptr;
            for (const Verdict& e : expected)
                if (kAssimp + e.file == f) v = &e;
            ASSERT_NE(v, nullptr) << "no verdict listed for this file: add one";
            ++listed;
            if (v->triangles > 0) {
                ASSERT_TRUE(r.ok) << r.error;
                EXPECT_EQ(r.scene.triangle_count(), v->triangles);
            } else {
                ASSERT_FALSE(r.ok) << "loaded " << r.scene.triangle_count() << " triangles";
                EXPECT_EQ(r.error.rfind(f + ": ", 0), 0u) << r.error;
                EXPECT_NE(r.error.find(v->error), std::string::npos) << r.error;
            }
        }
    }
    EXPECT_EQ(listed, std::size(expected)) << "a listed file is missing from the corpus";
}

TEST(GltfAssimp, SpecificMalformedFilesGiveTheRightError) {
    if (!exists(kAssimp)) GTEST_SKIP();
    auto r = import_files({kAssimp + "RecursiveNodes/RecursiveNodes.gltf"});
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.error.find("recursive"), std::string::npos) << r.error;
    r = import_files({kAssimp + "IndexOutOfRange/IndexOutOfRange.gltf"});
    EXPECT_FALSE(r.ok);
    EXPECT_NE(r.error.find("out of range"), std::string::npos) << r.error;
    r = import_files({kAssimp + "MissingBin/BoxTextured.gltf"});
    EXPECT_FALSE(r.ok);
}

TEST(GltfAssimp, EveryCorpusFileLoadsOrFailsCleanly) {
    if (!exists(kAssimp)) GTEST_SKIP();
    size_t loaded = 0, failed = 0;
    for (const std::string& f : files_in(kAssimp)) {
        const auto r = import_files({f});
        if (!r.ok) {
            EXPECT_EQ(r.error.rfind(f + ": ", 0), 0u) << r.error;
        }
        (r.ok ? loaded : failed)++;
    }
    std::printf("  %zu loaded, %zu rejected\n", loaded, failed);
    EXPECT_GT(loaded, 0u);
}

void expect_bounds_near(const Aabb& a, const Aabb& b, float tol) {
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(a.lo[size_t(k)], b.lo[size_t(k)], tol);
        EXPECT_NEAR(a.hi[size_t(k)], b.hi[size_t(k)], tol);
    }
}

TEST(GltfAssimp, DracoEngineMatchesItsUncompressedTriangleCount) {
    // The same model uncompressed is in the same corpus. Its encoder (Draco) dropped the
    // zero-area triangles, so the Draco file's input is the uncompressed file's triangles
    // after the cleaner dropped those (the figure this test once hard-coded, 110,336); Draco's
    // quantization then collapses a few more (at most 0.1%); bounds agree to a fraction of
    // the extent.
    const std::string f = kAssimp + "draco/2CylinderEngine.gltf";
    const std::string plain = kAssimp + "2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
    if (!exists(f) && !exists(plain)) GTEST_SKIP() << kAssimp << " not installed";
    ASSERT_TRUE(exists(f)) << f;
    ASSERT_TRUE(exists(plain)) << plain;
    const auto r = import_files({f}), u = import_files({plain});
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_TRUE(u.ok) << u.error;
    ASSERT_GT(u.scene.triangle_count(), 0u);
    EXPECT_GT(u.scene.dropped.at("degenerate"), 0u);
    EXPECT_EQ(u.scene.input_triangles, u.scene.triangle_count() + u.scene.dropped.at("degenerate"));
    EXPECT_EQ(r.scene.input_triangles, u.scene.triangle_count());
    EXPECT_LE(r.scene.triangle_count(), u.scene.triangle_count());
    EXPECT_GE(double(r.scene.triangle_count()), 0.999 * double(u.scene.triangle_count()));
    const Aabb a = bounds(r.scene), b = bounds(u.scene);
    float extent = 0;
    for (int k = 0; k < 3; ++k) extent = std::max(extent, b.hi[size_t(k)] - b.lo[size_t(k)]);
    expect_bounds_near(a, b, 1e-3f * extent);
}

// ---------------------------------------------------------------------------
// Shared real scenes.
// ---------------------------------------------------------------------------

const std::string kScenes = ::cwbvh::test::scene_corpus_dir();

TEST(GltfScenes, BunnyObjGlbAndDracoAgree) {
    const std::string obj = kScenes + "/bunny.obj", glb = kScenes + "/bunny.glb",
                      drc = kScenes + "/bunny_draco.glb";
    for (const std::string& f : {obj, glb, drc}) CWBVH_REQUIRE_SCENE(f);
    const auto o = import_files({obj}), g = import_files({glb}), d = import_files({drc});
    ASSERT_TRUE(o.ok) << o.error;
    ASSERT_TRUE(g.ok) << g.error;
    ASSERT_TRUE(d.ok) << d.error;
    EXPECT_EQ(o.scene.triangle_count(), 69666u);
    EXPECT_EQ(g.scene.triangle_count(), 69666u);
    EXPECT_EQ(d.scene.triangle_count(), 69666u);
    // Same float positions, same triangles, same order.
    EXPECT_EQ(o.scene.indices, g.scene.indices);
    EXPECT_EQ(o.scene.vertices, g.scene.vertices);
    expect_bounds_near(bounds(d.scene), bounds(g.scene), 1e-4f);
}

TEST(GltfScenes, DragonObjAndGlbAgree) {
    const std::string obj = kScenes + "/dragon_res4.obj", glb = kScenes + "/dragon_res4.glb";
    for (const std::string& f : {obj, glb}) CWBVH_REQUIRE_SCENE(f);
    const auto o = import_files({obj}), g = import_files({glb});
    ASSERT_TRUE(o.ok) << o.error;
    ASSERT_TRUE(g.ok) << g.error;
    EXPECT_EQ(o.scene.triangle_count(), 11102u);
    EXPECT_EQ(g.scene.triangle_count(), 11102u);
    const Aabb a = bounds(o.scene), b = bounds(g.scene);
    EXPECT_EQ(a.lo, b.lo);
    EXPECT_EQ(a.hi, b.hi);
    // Triangle by triangle the same positions (OpenMesh may duplicate
    // vertices of non-manifold faces, so compare positions, not indices).
    for (size_t i = 0; i < o.scene.triangle_count(); ++i)
        ASSERT_EQ(o.scene.triangle(i), g.scene.triangle(i)) << i;
}

TEST(GltfScenes, DracoCg57CountsMatchSceneNotes) {
    const std::string f = kScenes + "/fg_cg57_draco.glb";
    CWBVH_REQUIRE_SCENE(f);
    const auto r = import_files({f});
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scene.input_triangles, 180063u);
    EXPECT_EQ(r.scene.dropped.at("degenerate"), 505u);
}

TEST(GltfScenes, MergeGlbAndObj) {
    const std::string obj = kScenes + "/dragon_res4.obj", glb = kScenes + "/bunny.glb";
    for (const std::string& f : {obj, glb}) CWBVH_REQUIRE_SCENE(f);
    const auto r = import_files({glb, obj});
    ASSERT_TRUE(r.ok) << r.error;
    ASSERT_EQ(r.scene.triangle_count(), 69666u + 11102u);
    EXPECT_EQ(r.scene.sources.front().input, 0u);
    EXPECT_EQ(r.scene.sources[69666].input, 1u);
    EXPECT_EQ(r.scene.sources[69666].triangle, 0u);
    EXPECT_EQ(r.scene.sources.back().input, 1u);
}

}  // namespace
}  // namespace cwbvh::compiler::test

namespace cwbvh::compiler::test {
namespace {

std::string read_all(const std::string& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

TEST(Draco, DrcFileDecodesAndGarbageIsRejected) {
    const std::string glb = kScenes + "/bunny_draco.glb";
    CWBVH_REQUIRE_SCENE(glb);
    // The compressed bufferView is a complete Draco stream; cut it out of the
    // GLB (trailing bytes after the stream are ignored by the decoder).
    const std::string bytes = read_all(glb);
    const size_t at = bytes.find("DRACO");
    ASSERT_NE(at, std::string::npos);
    TempDir dir;
    const auto r = import_files({dir.write("bunny.drc", bytes.substr(at))});
    ASSERT_TRUE(r.ok) << r.error;
    EXPECT_EQ(r.scene.triangle_count(), 69666u);
    // Detected by magic whatever the extension.
    EXPECT_TRUE(import_files({dir.write("bunny.bin", bytes.substr(at))}).ok);
    for (size_t cut : {5u, 16u, 64u, 1000u, 20000u}) {
        const auto t = import_files({dir.write("t.drc", bytes.substr(at, cut))});
        EXPECT_FALSE(t.ok) << cut;
    }
    std::string flipped = bytes.substr(at);
    for (size_t i = 40; i < flipped.size(); i += 997) flipped[i] = char(flipped[i] ^ 0x5a);
    const auto f = import_files({dir.write("f.drc", flipped)});  // must not crash
    if (!f.ok) {
        EXPECT_NE(f.error.find("f.drc"), std::string::npos);
    }
}

TEST(Draco, CorruptDracoInsideGlbIsRejected) {
    const std::string glb = kScenes + "/bunny_draco.glb";
    CWBVH_REQUIRE_SCENE(glb);
    std::string bytes = read_all(glb);
    const size_t at = bytes.find("DRACO");
    ASSERT_NE(at, std::string::npos);
    bytes[at] = 'X';  // bad magic inside the compressed bufferView
    TempDir dir;
    const auto r = import_files({dir.write("bad.glb", bytes)});
    ASSERT_FALSE(r.ok);
    EXPECT_NE(r.error.find("mesh 0 primitive 0"), std::string::npos) << r.error;
}

}  // namespace
}  // namespace cwbvh::compiler::test
