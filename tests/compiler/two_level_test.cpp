// Two-level files (issue 19) from cwbvhc's pipeline: the instanced/flattened
// decision, byte-identical single-level output, determinism across threads,
// 10^5 placements, mirrored, singular, near-singular and far-away transforms.
// Each written file is parsed here and checked structurally: every mesh's
// node range is one tree with absolute indices inside its ranges, decoded
// boxes contain the triangles, the TLAS holds every instance exactly once in
// leaf order and its slot boxes contain the instance world boxes, which
// contain the transformed mesh boxes.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <tuple>
#include <string>
#include <vector>

#include "cli_support.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/model.h"
#include "cwbvh/compiler/progress.h"
#include "cwbvh/compiler/two_level.h"
#include "cwbvh/format/format.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/source_map.h"
#include "cwbvh/format/transform.h"

namespace cwbvh::compiler {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------
// A tiny glTF writer (embedded base64 buffer).
// ---------------------------------------------------------------------------

struct TestMesh {
    std::vector<float> positions;  ///< x, y, z per vertex
    std::vector<uint32_t> indices;
};

struct TestNode {
    int mesh = -1;
    std::string transform;  ///< JSON members, e.g. "\"translation\":[1,2,3]" (empty: identity)
};

std::string base64(const std::vector<uint8_t>& data) {
    static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    size_t i = 0;
    for (; i + 2 < data.size(); i += 3) {
        const uint32_t v = uint32_t(data[i]) << 16 | uint32_t(data[i + 1]) << 8 | data[i + 2];
        for (int s = 18; s >= 0; s -= 6) out += k[(v >> s) & 63];
    }
    if (i < data.size()) {
        uint32_t v = uint32_t(data[i]) << 16;
        if (i + 1 < data.size()) v |= uint32_t(data[i + 1]) << 8;
        out += k[(v >> 18) & 63];
        out += k[(v >> 12) & 63];
        out += i + 1 < data.size() ? k[(v >> 6) & 63] : '=';
        out += '=';
    }
    return out;
}

void write_gltf(const fs::path& path, const std::vector<TestMesh>& meshes, const std::vector<TestNode>& nodes) {
    std::vector<uint8_t> buffer;
    std::string accessors, views, json_meshes;
    auto append = [&](const void* p, size_t n) {
        const size_t offset = buffer.size();
        buffer.insert(buffer.end(), static_cast<const uint8_t*>(p), static_cast<const uint8_t*>(p) + n);
        return offset;
    };
    int view = 0;
    for (size_t m = 0; m < meshes.size(); ++m) {
        const TestMesh& mesh = meshes[m];
        float lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
        for (size_t i = 0; i < mesh.positions.size(); ++i) {
            lo[i % 3] = std::min(lo[i % 3], mesh.positions[i]);
            hi[i % 3] = std::max(hi[i % 3], mesh.positions[i]);
        }
        const size_t po = append(mesh.positions.data(), mesh.positions.size() * 4);
        const size_t io = append(mesh.indices.data(), mesh.indices.size() * 4);
        char buf[512];
        std::snprintf(buf, sizeof buf, "%s{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu},{\"buffer\":0,\"byteOffset\":%zu,\"byteLength\":%zu}",
                      views.empty() ? "" : ",", po, mesh.positions.size() * 4, io, mesh.indices.size() * 4);
        views += buf;
        std::snprintf(buf, sizeof buf,
                      "%s{\"bufferView\":%d,\"componentType\":5126,\"count\":%zu,\"type\":\"VEC3\",\"min\":[%.9g,%.9g,%.9g],\"max\":[%.9g,%.9g,%.9g]},"
                      "{\"bufferView\":%d,\"componentType\":5125,\"count\":%zu,\"type\":\"SCALAR\"}",
                      accessors.empty() ? "" : ",", view, mesh.positions.size() / 3, lo[0], lo[1], lo[2], hi[0], hi[1],
                      hi[2], view + 1, mesh.indices.size());
        accessors += buf;
        std::snprintf(buf, sizeof buf, "%s{\"primitives\":[{\"attributes\":{\"POSITION\":%d},\"indices\":%d}]}",
                      json_meshes.empty() ? "" : ",", view, view + 1);
        json_meshes += buf;
        view += 2;
    }
    std::string json = "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[";
    for (size_t n = 0; n < nodes.size(); ++n) json += (n ? "," : "") + std::to_string(n);
    json += "]}],\"nodes\":[";
    for (size_t n = 0; n < nodes.size(); ++n) {
        json += n ? ",{" : "{";
        std::string members;
        if (nodes[n].mesh >= 0) members = "\"mesh\":" + std::to_string(nodes[n].mesh);
        if (!nodes[n].transform.empty()) members += (members.empty() ? "" : ",") + nodes[n].transform;
        json += members + "}";
    }
    json += "],\"meshes\":[" + json_meshes + "],\"accessors\":[" + accessors + "],\"bufferViews\":[" + views +
            "],\"buffers\":[{\"byteLength\":" + std::to_string(buffer.size()) +
            ",\"uri\":\"data:application/octet-stream;base64," + base64(buffer) + "\"}]}";
    std::ofstream(path, std::ios::binary) << json;
}

/// A closed box of 12 triangles, [x0, x0+1] x [0, 1] x [0, 2].
TestMesh box_mesh(float x0 = 0.0f) {
    TestMesh m;
    for (int k = 0; k < 8; ++k) {
        m.positions.push_back(x0 + float(k & 1));
        m.positions.push_back(float((k >> 1) & 1));
        m.positions.push_back(2.0f * float((k >> 2) & 1));
    }
    m.indices = {0, 1, 3, 0, 3, 2, 4, 7, 5, 4, 6, 7, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6, 0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3};
    return m;
}

/// A small tetrahedron (4 triangles).
TestMesh tetra_mesh() {
    TestMesh m;
    m.positions = {0, 0, 0, 0.5f, 0, 0, 0, 0.5f, 0, 0, 0, 0.5f};
    m.indices = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
    return m;
}

std::string translation(double x, double y, double z) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "\"translation\":[%.17g,%.17g,%.17g]", x, y, z);
    return buf;
}

// ---------------------------------------------------------------------------
// The written file, parsed.
// ---------------------------------------------------------------------------

struct Parsed {
    FileHeader header{};
    std::map<uint32_t, SectionEntry> sections;
    std::string bytes;
    template <class T>
    std::vector<T> array(uint32_t type) const {
        const auto it = sections.find(type);
        if (it == sections.end()) return {};
        std::vector<T> out(it->second.size / sizeof(T));
        std::memcpy(out.data(), bytes.data() + it->second.offset, out.size() * sizeof(T));
        return out;
    }
    bool has(uint32_t type) const { return sections.count(type) != 0; }
};

Parsed parse(const fs::path& path) {
    Parsed p;
    p.bytes = test::slurp(path);
    EXPECT_GE(p.bytes.size(), sizeof(FileHeader));
    if (p.bytes.size() < sizeof(FileHeader)) return p;
    std::memcpy(&p.header, p.bytes.data(), sizeof p.header);
    for (uint32_t i = 0; i < p.header.section_count; ++i) {
        SectionEntry e;
        std::memcpy(&e, p.bytes.data() + p.header.section_table_offset + i * sizeof(SectionEntry), sizeof e);
        p.sections[e.type] = e;
    }
    return p;
}

bool box_contains(const float lo[3], const float hi[3], const float plo[3], const float phi[3]) {
    for (int a = 0; a < 3; ++a)
        if (!(lo[a] <= plo[a] && hi[a] >= phi[a])) return false;
    return true;
}

/// Walks one 8-wide tree from `root`; `leaf(first_record, count, slot box)` per leaf slot.
/// Checks: nodes inside [node_lo, node_hi), each visited once, children after parents.
template <class Leaf>
void walk(const std::vector<CwbvhNode>& nodes, uint32_t root, uint32_t node_lo, uint32_t node_hi,
          std::vector<uint8_t>& visited, Leaf&& leaf) {
    std::vector<uint32_t> stack{root};
    while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        ASSERT_GE(i, node_lo);
        ASSERT_LT(i, node_hi);
        ASSERT_EQ(visited[i]++, 0) << "node " << i << " reached twice";
        const CwbvhNode& n = nodes[i];
        for (int s = 0; s < kWidth; ++s) {
            const uint8_t m = n.meta[s];
            if (m == kMetaEmpty) continue;
            float lo[3], hi[3];
            decode_slot_box(n, s, lo, hi);
            if (meta_is_internal(m)) {
                const uint32_t c = internal_child_index(n, s);
                ASSERT_GT(c, i);
                stack.push_back(c);
            } else {
                leaf(n.tri_base + uint32_t(meta_leaf_offset(m)), meta_leaf_count(m), lo, hi);
            }
        }
    }
}

/// The structural checks of a two-level file (see the file comment).
void check_two_level(const Parsed& f) {
    ASSERT_TRUE(f.has(kSectionMeshes) && f.has(kSectionInstances) && f.has(kSectionTopNodes));
    for (uint32_t t : {kSectionMeshes, kSectionInstances, kSectionTopNodes})
        EXPECT_EQ(f.sections.at(t).flags & kSectionRequired, uint32_t(kSectionRequired));
    const auto nodes = f.array<CwbvhNode>(kSectionNodes);
    const auto tris = f.array<TriangleRecord>(kSectionTriangles);
    const auto meshes = f.array<MeshRecord>(kSectionMeshes);
    const auto insts = f.array<InstanceRecord>(kSectionInstances);
    const auto tlas = f.array<CwbvhNode>(kSectionTopNodes);
    const auto pmap = f.array<SourceRange>(kSectionSourceMap);
    ASSERT_FALSE(meshes.empty());
    uint64_t prims = 0;
    for (const SourceRange& r : pmap) prims += r.count;
    // Meshes: contiguous, covering, one tree each.
    uint32_t node_next = 0, tri_next = 0, prim_next = 0;
    std::vector<uint8_t> visited(nodes.size(), 0), tri_used(tris.size(), 0);
    for (size_t m = 0; m < meshes.size(); ++m) {
        const MeshRecord& mr = meshes[m];
        ASSERT_EQ(mr.node_first, node_next);
        ASSERT_EQ(mr.tri_first, tri_next);
        ASSERT_EQ(mr.prim_first, prim_next);
        node_next += mr.node_count;
        tri_next += mr.tri_count;
        prim_next += mr.prim_count;
        walk(nodes, mr.node_first, mr.node_first, mr.node_first + mr.node_count, visited,
             [&](uint32_t first, int count, const float* lo, const float* hi) {
                 for (int k = 0; k < count; ++k) {
                     const uint32_t t = first + uint32_t(k);
                     ASSERT_GE(t, mr.tri_first);
                     ASSERT_LT(t, mr.tri_first + mr.tri_count);
                     ASSERT_EQ(tri_used[t]++, 0);
                     const TriangleRecord& rec = tris[t];
                     EXPECT_GE(rec.prim, mr.prim_first);
                     EXPECT_LT(rec.prim, mr.prim_first + mr.prim_count);
                     for (const float* v : {rec.v0, rec.v1, rec.v2}) {
                         EXPECT_TRUE(box_contains(lo, hi, v, v)) << "mesh " << m << " record " << t;
                         EXPECT_TRUE(box_contains(mr.lo, mr.hi, v, v)) << "mesh " << m << " record " << t;
                     }
                 }
             });
    }
    EXPECT_EQ(node_next, nodes.size());
    EXPECT_EQ(tri_next, tris.size());
    EXPECT_EQ(prim_next, prims);
    for (size_t i = 0; i < nodes.size(); ++i) EXPECT_EQ(visited[i], 1) << "node " << i;
    for (size_t t = 0; t < tris.size(); ++t) EXPECT_EQ(tri_used[t], 1) << "record " << t;
    // Instances: transform and world box.
    for (size_t i = 0; i < insts.size(); ++i) {
        const InstanceRecord& in = insts[i];
        ASSERT_LT(in.mesh, meshes.size());
        const MeshRecord& mr = meshes[in.mesh];
        for (int k = 0; k < 8; ++k) {
            const double c[3] = {(k & 1) ? mr.hi[0] : mr.lo[0], (k & 2) ? mr.hi[1] : mr.lo[1], (k & 4) ? mr.hi[2] : mr.lo[2]};
            for (int r = 0; r < 3; ++r) {
                const double w = double(in.object_to_world[r][0]) * c[0] + double(in.object_to_world[r][1]) * c[1] +
                                 double(in.object_to_world[r][2]) * c[2] + double(in.object_to_world[r][3]);
                EXPECT_LE(double(in.world_lo[r]), w) << "instance " << i;
                EXPECT_GE(double(in.world_hi[r]), w) << "instance " << i;
            }
        }
        // world_to_object * object_to_world = identity (float rounding only).
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) {
                double v = 0;
                for (int k = 0; k < 3; ++k) v += double(in.world_to_object[r][k]) * double(in.object_to_world[k][c]);
                EXPECT_NEAR(v, r == c ? 1.0 : 0.0, 1e-5) << "instance " << i;
            }
    }
    // TLAS: every instance once, in leaf order, inside its slot boxes.
    ASSERT_FALSE(tlas.empty());
    std::vector<uint8_t> tlas_visited(tlas.size(), 0), inst_used(insts.size(), 0);
    uint32_t next_record = 0;
    walk(tlas, 0, 0, uint32_t(tlas.size()), tlas_visited, [&](uint32_t first, int count, const float* lo, const float* hi) {
        ASSERT_GE(count, 1);
        ASSERT_LE(count, 3);
        for (int k = 0; k < count; ++k) {
            const uint32_t i = first + uint32_t(k);
            ASSERT_LT(i, insts.size());
            ASSERT_EQ(inst_used[i]++, 0);
            EXPECT_TRUE(box_contains(lo, hi, insts[i].world_lo, insts[i].world_hi)) << "instance " << i;
        }
        next_record += uint32_t(count);
    });
    for (size_t i = 0; i < tlas.size(); ++i) EXPECT_EQ(tlas_visited[i], 1) << "TLAS node " << i;
    for (size_t i = 0; i < insts.size(); ++i) EXPECT_EQ(inst_used[i], 1) << "instance " << i;
    // BNDS = union of the instance world boxes.
    const auto bounds = f.array<SceneBounds>(kSectionBounds);
    ASSERT_EQ(bounds.size(), 1u);
    for (const InstanceRecord& in : insts) EXPECT_TRUE(box_contains(bounds[0].lo, bounds[0].hi, in.world_lo, in.world_hi));
}

Result compile_file(const fs::path& in, const fs::path& out, int threads, bool flatten, CompileStats& stats) {
    CompileOptions o;
    o.inputs = {in.string()};
    o.output = out.string();
    o.threads = threads;
    o.flatten = flatten;
    return compile(o, stats);
}

// ---------------------------------------------------------------------------

TEST(TwoLevel, MeshPlacedTwiceGivesInstancesPlacedOnceIsMerged) {
    const fs::path dir = test::temp_dir("two_level_decision");
    // Mesh 0 placed three times (one mirrored), mesh 1 and 2 once each.
    write_gltf(dir / "s.gltf", {box_mesh(), tetra_mesh(), box_mesh(5.0f)},
               {{0, translation(10, 0, 0)},
                {1, translation(0, 3, 0)},
                {0, "\"scale\":[-1,1,1]"},
                {2, ""},
                {0, "\"rotation\":[0,0,0.38268343236508984,0.92387953251128674],\"scale\":[2,2,2]"}});
    CompileStats stats;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "s.cwbvh", 2, false, stats).ok());
    EXPECT_TRUE(stats.two_level);
    EXPECT_EQ(stats.meshes, 2u);     // mesh 0, then the merged meshes 1 and 2
    EXPECT_EQ(stats.instances, 4u);  // three placements of mesh 0 + the identity instance
    EXPECT_EQ(stats.triangles, 12u + 4u + 12u);
    EXPECT_EQ(stats.instanced_triangles, 3 * 12u + 4u + 12u);
    const Parsed f = parse(dir / "s.cwbvh");
    check_two_level(f);
    const auto meshes = f.array<MeshRecord>(kSectionMeshes);
    ASSERT_EQ(meshes.size(), 2u);
    EXPECT_EQ(meshes[0].source_mesh, 0u);
    EXPECT_EQ(meshes[1].source_mesh, kInvalidIndex);
    // Mesh 0 is in object space: its box is the glTF box.
    EXPECT_EQ(meshes[0].lo[0], 0.0f);
    EXPECT_EQ(meshes[0].hi[2], 2.0f);
    // The merged level is in world space (the tetrahedron moved by +3 in y).
    EXPECT_EQ(meshes[1].hi[1], 3.5f);
    const auto insts = f.array<InstanceRecord>(kSectionInstances);
    int mirrored = 0, identity = 0;
    for (const InstanceRecord& in : insts) {
        const auto& m = in.object_to_world;
        const double det = double(m[0][0]) * (double(m[1][1]) * m[2][2] - double(m[1][2]) * m[2][1]) -
                           double(m[0][1]) * (double(m[1][0]) * m[2][2] - double(m[1][2]) * m[2][0]) +
                           double(m[0][2]) * (double(m[1][0]) * m[2][1] - double(m[1][1]) * m[2][0]);
        mirrored += det < 0;
        if (in.source_node == kInvalidIndex) {
            ++identity;
            EXPECT_EQ(in.mesh, 1u);
            EXPECT_EQ(m[0][0], 1.0f);
            EXPECT_EQ(m[0][3], 0.0f);
        } else {
            EXPECT_EQ(in.mesh, 0u);
            EXPECT_TRUE(in.source_node == 0 || in.source_node == 2 || in.source_node == 4);
        }
    }
    EXPECT_EQ(mirrored, 1);
    EXPECT_EQ(identity, 1);

    // --flatten: today's single-level file with every placement.
    CompileStats flat;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "flat.cwbvh", 2, true, flat).ok());
    EXPECT_FALSE(flat.two_level);
    EXPECT_EQ(flat.triangles, 3 * 12u + 4u + 12u);
    const Parsed ff = parse(dir / "flat.cwbvh");
    EXPECT_FALSE(ff.has(kSectionMeshes) || ff.has(kSectionInstances) || ff.has(kSectionTopNodes));
}

/// Source key (glTF mesh, primitive, triangle) -> world triangles, from a file:
/// a single-level file's stored triangles, or every instance of a two-level
/// file with its mesh's triangles mapped by object_to_world (in double).
using WorldTriangles = std::map<std::tuple<uint32_t, uint32_t, uint32_t>, std::vector<std::array<double, 9>>>;
WorldTriangles world_triangles(const Parsed& f) {
    const auto tris = f.array<TriangleRecord>(kSectionTriangles);
    const auto pmap = f.array<SourceRange>(kSectionSourceMap);
    uint64_t stored = 0;
    for (const SourceRange& r : pmap) stored += r.count;
    std::vector<const TriangleRecord*> by_prim(stored, nullptr);  // one record per stored triangle
    for (const TriangleRecord& t : tris) by_prim.at(t.prim) = &t;
    auto key = [&](uint32_t prim) {
        const auto s = find_source(pmap, prim);
        EXPECT_TRUE(s.has_value());
        return std::make_tuple(s->mesh, s->primitive, s->triangle);
    };
    WorldTriangles out;
    if (!f.has(kSectionInstances)) {
        for (uint32_t p = 0; p < stored; ++p) {
            const TriangleRecord& t = *by_prim[p];
            out[key(p)].push_back({t.v0[0], t.v0[1], t.v0[2], t.v1[0], t.v1[1], t.v1[2], t.v2[0], t.v2[1], t.v2[2]});
        }
        return out;
    }
    const auto meshes = f.array<MeshRecord>(kSectionMeshes);
    for (const InstanceRecord& in : f.array<InstanceRecord>(kSectionInstances)) {
        const MeshRecord& m = meshes.at(in.mesh);
        for (uint32_t p = m.prim_first; p < m.prim_first + m.prim_count; ++p) {
            const TriangleRecord& t = *by_prim[p];
            std::array<double, 9> w{};
            const float* v[3] = {t.v0, t.v1, t.v2};
            for (int k = 0; k < 3; ++k)
                for (int r = 0; r < 3; ++r)
                    w[size_t(3 * k + r)] = double(in.object_to_world[r][0]) * v[k][0] +
                                           double(in.object_to_world[r][1]) * v[k][1] +
                                           double(in.object_to_world[r][2]) * v[k][2] + double(in.object_to_world[r][3]);
            out[key(p)].push_back(w);
        }
    }
    return out;
}

TEST(TwoLevel, InstancesExpandToTheFlattenedGeometry) {
    // Every glTF triangle of every placement, in the instanced file (mesh
    // triangles under the instance transform) and in the flattened file (world
    // space), matched one to one by source triangle within float rounding.
    const fs::path dir = test::temp_dir("two_level_expand");
    write_gltf(dir / "s.gltf", {box_mesh(), tetra_mesh(), box_mesh(5.0f)},
               {{0, translation(10, 0, 0)},
                {1, translation(0, 3, 0)},
                {0, "\"scale\":[-1,1,1]"},
                {2, ""},
                {1, "\"rotation\":[0.5,0.5,0.5,0.5],\"translation\":[-4,2,1]"},
                {0, "\"rotation\":[0,0,0.38268343236508984,0.92387953251128674],\"scale\":[2,2,2]"}});
    CompileStats a, b;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "i.cwbvh", 2, false, a).ok());
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "f.cwbvh", 2, true, b).ok());
    ASSERT_TRUE(a.two_level);
    const WorldTriangles inst = world_triangles(parse(dir / "i.cwbvh"));
    const WorldTriangles flat = world_triangles(parse(dir / "f.cwbvh"));
    ASSERT_EQ(inst.size(), flat.size());
    size_t matched = 0;
    for (const auto& [k, list] : flat) {
        ASSERT_TRUE(inst.count(k));
        std::vector<std::array<double, 9>> left = inst.at(k);
        ASSERT_EQ(left.size(), list.size());
        for (const auto& t : list) {
            bool found = false;
            for (size_t i = 0; i < left.size() && !found; ++i) {
                bool close = true;
                for (int c = 0; c < 9; ++c) close = close && std::fabs(left[i][size_t(c)] - t[size_t(c)]) <= 1e-5;
                if (close) {
                    left.erase(left.begin() + std::ptrdiff_t(i));
                    found = true;
                }
            }
            EXPECT_TRUE(found) << "a flattened triangle of source mesh " << std::get<0>(k) << " has no instanced twin";
            matched += found;
        }
    }
    EXPECT_EQ(matched, size_t(b.triangles));
    EXPECT_EQ(a.instanced_triangles, b.triangles);
}

TEST(TwoLevel, StatsReportMeshesInstancesAndTrianglesInJsonAndTable) {
    const fs::path dir = test::temp_dir("two_level_stats");
    write_gltf(dir / "s.gltf", {box_mesh(), tetra_mesh()}, {{0, ""}, {0, translation(3, 0, 0)}, {1, ""}});
    const std::string json = (dir / "s.json").string();
    const test::RunResult r =
        test::run_tool("cwbvhc", {(dir / "s.gltf").string(), "-o", (dir / "s.cwbvh").string(), "--stats-json", json});
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const auto j = nlohmann::json::parse(test::slurp(json));
    EXPECT_EQ(j["two_level"], true);
    EXPECT_EQ(j["meshes"], 2);
    EXPECT_EQ(j["instances"], 3);
    EXPECT_EQ(j["distinct_triangles"], 16);
    EXPECT_EQ(j["instanced_triangles"], 28);
    EXPECT_EQ(j["triangles"], 16);
    EXPECT_GE(j["top_nodes"].get<int>(), 1);
    for (const char* phase : {"import", "meshes", "assemble", "instances", "tlas", "write"})
        EXPECT_TRUE(j["seconds"].contains(phase)) << phase;
    for (const char* phase : {"sbvh", "collapse", "slots", "encode"})
        EXPECT_TRUE(j["mesh_phase_seconds"].contains(phase)) << phase;
    EXPECT_TRUE(j["bytes"].contains("MESH") && j["bytes"].contains("INST") && j["bytes"].contains("TLAS"));
    EXPECT_NE(r.out.find("instanced triangles"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("two-level: instances"), std::string::npos) << r.out;
    // --flatten: single-level, instanced = stored.
    const test::RunResult f = test::run_tool(
        "cwbvhc", {(dir / "s.gltf").string(), "-o", (dir / "f.cwbvh").string(), "--flatten", "--stats-json", json, "--quiet"});
    ASSERT_EQ(f.exit_code, 0) << f.err;
    const auto k = nlohmann::json::parse(test::slurp(json));
    EXPECT_EQ(k["two_level"], false);
    EXPECT_EQ(k["triangles"], 28);
    EXPECT_EQ(k["instanced_triangles"], 28);
}

TEST(TwoLevel, MeshesPhaseCountsTheDistinctTriangles) {
    const fs::path dir = test::temp_dir("two_level_progress");
    write_gltf(dir / "s.gltf", {box_mesh(), tetra_mesh()}, {{0, ""}, {0, translation(3, 0, 0)}, {1, ""}, {1, translation(0, 4, 0)}});
    CompileOptions o;
    o.inputs = {(dir / "s.gltf").string()};
    o.output = (dir / "s.cwbvh").string();
    o.threads = 2;
    Progress progress;
    std::vector<std::string> counted;
    CompileStats stats;
    const Result r = compile(o, stats, [&](const std::string& phase, bool done, double) {
        if (done && phase == "meshes") {
            EXPECT_EQ(progress.total.load(), 16u);
            EXPECT_EQ(progress.done.load(), 16u);
            counted.push_back(phase);
        }
    }, &progress);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_EQ(counted.size(), 1u);
}

TEST(TwoLevel, ACallbackThatThrowsCancelsTheCompileBeforeTheWrite) {
    // compile.h's cancellation on the two-level phases (meshes, assemble, ..., write): a throw at
    // any phase start or end before the write's end writes nothing.
    const fs::path dir = test::temp_dir("two_level_cancel");
    write_gltf(dir / "s.gltf", {box_mesh(), tetra_mesh()}, {{0, ""}, {0, translation(3, 0, 0)}, {1, ""}});
    CompileOptions o;
    o.inputs = {(dir / "s.gltf").string()};
    o.output = (dir / "full.cwbvh").string();
    o.threads = 2;
    std::vector<std::string> calls;
    CompileStats full;
    const Result r = compile(o, full, [&](const std::string& phase, bool done, double) {
        calls.push_back(phase + (done ? " end" : " start"));
    });
    ASSERT_TRUE(r.ok()) << r.message;
    ASSERT_TRUE(full.two_level);
    ASSERT_EQ(calls.back(), "write end");
    struct Stop {};
    o.output = (dir / "cancelled.cwbvh").string();
    for (size_t at = 0; at + 1 < calls.size(); ++at) {
        SCOPED_TRACE(calls[at]);
        size_t n = 0;
        CompileStats stats;
        EXPECT_THROW(compile(o, stats, [&](const std::string&, bool, double) {
            if (n++ == at) throw Stop{};
        }), Stop);
        EXPECT_EQ(n, at + 1);
        EXPECT_FALSE(fs::exists(o.output));
    }
}

TEST(TwoLevel, NoMeshPlacedTwiceGivesTheSingleLevelFileByteForByte) {
    const fs::path dir = test::temp_dir("two_level_single");
    write_gltf(dir / "s.gltf", {box_mesh(), tetra_mesh()}, {{0, translation(1, 0, 0)}, {1, ""}, {-1, ""}});
    CompileStats a, b;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "default.cwbvh", 2, false, a).ok());
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "flat.cwbvh", 2, true, b).ok());
    EXPECT_FALSE(a.two_level);
    EXPECT_EQ(test::slurp(dir / "default.cwbvh"), test::slurp(dir / "flat.cwbvh"));
    EXPECT_FALSE(parse(dir / "default.cwbvh").has(kSectionMeshes));
    // A mesh placed twice whose triangles are all degenerate: nothing left to
    // instance, the single-level file of --flatten.
    TestMesh flat_mesh;
    flat_mesh.positions = {0, 0, 0, 1, 0, 0, 2, 0, 0};
    flat_mesh.indices = {0, 1, 2};
    write_gltf(dir / "d.gltf", {flat_mesh, tetra_mesh()}, {{0, ""}, {0, translation(1, 0, 0)}, {1, ""}});
    CompileStats d, e;
    ASSERT_TRUE(compile_file(dir / "d.gltf", dir / "d.cwbvh", 2, false, d).ok());
    ASSERT_TRUE(compile_file(dir / "d.gltf", dir / "e.cwbvh", 2, true, e).ok());
    EXPECT_FALSE(d.two_level);
    EXPECT_EQ(d.dropped_triangles["degenerate"], 2u);
    EXPECT_EQ(test::slurp(dir / "d.cwbvh"), test::slurp(dir / "e.cwbvh"));
    // An OBJ input is always single-level.
    test::write_obj(dir / "t.obj", {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}, {{0, 1, 2}});
    CompileStats c;
    ASSERT_TRUE(compile_file(dir / "t.obj", dir / "obj.cwbvh", 1, false, c).ok());
    EXPECT_FALSE(c.two_level);
}

TEST(TwoLevel, ByteIdenticalForAnyThreadCount) {
    const fs::path dir = test::temp_dir("two_level_threads");
    std::vector<TestMesh> meshes;
    std::vector<TestNode> nodes;
    for (int m = 0; m < 6; ++m) {
        TestMesh mesh;
        // A wavy strip of 2 * 40 * (m + 2) triangles: enough for several wide nodes.
        const int cols = 40 * (m + 2);
        for (int i = 0; i <= cols; ++i)
            for (int j = 0; j < 2; ++j) {
                mesh.positions.push_back(float(i) * 0.1f);
                mesh.positions.push_back(float(j));
                mesh.positions.push_back(std::sin(float(i) * 0.3f + float(m)));
            }
        for (int i = 0; i < cols; ++i) {
            const uint32_t a = uint32_t(2 * i);
            mesh.indices.insert(mesh.indices.end(), {a, a + 2, a + 1, a + 1, a + 2, a + 3});
        }
        meshes.push_back(mesh);
        for (int k = 0; k < 3 + m; ++k) nodes.push_back({m, translation(3.0 * k, 2.5 * m, 0.25 * k * m)});
    }
    write_gltf(dir / "s.gltf", meshes, nodes);
    CompileStats s1, s2;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "t1.cwbvh", 1, false, s1).ok());
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "t2.cwbvh", 2, false, s2).ok());
    EXPECT_TRUE(s1.two_level);
    EXPECT_EQ(s1.meshes, 6u);
    const std::string a = test::slurp(dir / "t1.cwbvh"), b = test::slurp(dir / "t2.cwbvh");
    EXPECT_FALSE(a.empty());
    EXPECT_EQ(a, b);
    check_two_level(parse(dir / "t1.cwbvh"));
}

TEST(TwoLevel, OneMeshPlacedOneHundredThousandTimes) {
    const fs::path dir = test::temp_dir("two_level_1e5");
    std::vector<TestNode> nodes;
    nodes.reserve(100000);
    for (int i = 0; i < 100000; ++i) nodes.push_back({0, translation(i % 100, (i / 100) % 100, i / 10000)});
    write_gltf(dir / "s.gltf", {tetra_mesh()}, nodes);
    CompileStats stats;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "s.cwbvh", 2, false, stats).ok());
    EXPECT_EQ(stats.meshes, 1u);
    EXPECT_EQ(stats.instances, 100000u);
    EXPECT_EQ(stats.instanced_triangles, 400000u);
    const Parsed f = parse(dir / "s.cwbvh");
    EXPECT_EQ(f.array<InstanceRecord>(kSectionInstances).size(), 100000u);
    check_two_level(f);
}

TEST(TwoLevel, SingularAndNearSingularTransformsAreRefusedNamingTheNode) {
    const fs::path dir = test::temp_dir("two_level_singular");
    write_gltf(dir / "flat.gltf", {box_mesh()}, {{0, ""}, {0, translation(1, 2, 3)}, {0, "\"scale\":[1,1,0]"}});
    CompileStats stats;
    Result r = compile_file(dir / "flat.gltf", dir / "out.cwbvh", 1, false, stats);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message.find((dir / "flat.gltf").string()), std::string::npos) << r.message;
    EXPECT_NE(r.message.find("glTF node 2"), std::string::npos) << r.message;
    EXPECT_NE(r.message.find("singular"), std::string::npos) << r.message;

    // Condition number 2^21 (just above the bound) is refused, 2^19 is not:
    // the bad case and the good case of the one threshold.
    write_gltf(dir / "thin.gltf", {box_mesh()}, {{0, ""}, {0, "\"scale\":[1,1,4.76837158203125e-07]"}});
    r = compile_file(dir / "thin.gltf", dir / "out.cwbvh", 1, false, stats);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message.find("glTF node 1"), std::string::npos) << r.message;
    EXPECT_NE(r.message.find("condition number"), std::string::npos) << r.message;
    write_gltf(dir / "ok.gltf", {box_mesh()}, {{0, ""}, {0, "\"scale\":[1,1,1.9073486328125e-06]"}});
    ASSERT_TRUE(compile_file(dir / "ok.gltf", dir / "ok.cwbvh", 1, false, stats).ok());
    check_two_level(parse(dir / "ok.cwbvh"));
    // --flatten compiles the singular file as today (the placement collapses to a plane).
    ASSERT_TRUE(compile_file(dir / "thin.gltf", dir / "flat.cwbvh", 1, true, stats).ok());

    // The command line: one line naming the file and the node, exit 1.
    const test::RunResult cli = test::run_tool("cwbvhc", {(dir / "flat.gltf").string(), "-o", (dir / "cli.cwbvh").string()});
    EXPECT_EQ(cli.exit_code, 1);
    EXPECT_EQ(test::count_lines(cli.err), 1) << cli.err;
    EXPECT_NE(cli.err.find("glTF node 2"), std::string::npos) << cli.err;
    EXPECT_FALSE(fs::exists(dir / "cli.cwbvh"));
}

TEST(TwoLevel, MirroredInstanceKeepsItsOrientationAndBox) {
    const fs::path dir = test::temp_dir("two_level_mirror");
    write_gltf(dir / "s.gltf", {box_mesh()}, {{0, "\"scale\":[-1,1,1]"}, {0, "\"scale\":[1,-2,1]"}});
    CompileStats stats;
    ASSERT_TRUE(compile_file(dir / "s.gltf", dir / "s.cwbvh", 1, false, stats).ok());
    const Parsed f = parse(dir / "s.cwbvh");
    check_two_level(f);
    for (const InstanceRecord& in : f.array<InstanceRecord>(kSectionInstances)) {
        if (in.source_node == 0) {
            EXPECT_EQ(in.world_to_object[0][0], -1.0f);
            EXPECT_LE(in.world_lo[0], -1.0f);
            EXPECT_GE(in.world_hi[0], 0.0f);
        } else {
            EXPECT_EQ(in.world_to_object[1][1], -0.5f);
            EXPECT_LE(in.world_lo[1], -2.0f);
        }
    }
}

TEST(TwoLevel, HugeTranslations) {
    const fs::path dir = test::temp_dir("two_level_far");
    // 1e30 is far but encodable (the quantizer's bound is 2^125 ~ 4.25e37).
    write_gltf(dir / "far.gltf", {box_mesh()}, {{0, ""}, {0, translation(1e30, -1e30, 3e29)}});
    CompileStats stats;
    ASSERT_TRUE(compile_file(dir / "far.gltf", dir / "far.cwbvh", 2, false, stats).ok());
    const Parsed f = parse(dir / "far.cwbvh");
    check_two_level(f);
    bool found = false;
    for (const InstanceRecord& in : f.array<InstanceRecord>(kSectionInstances)) {
        if (in.source_node != 1) continue;
        found = true;
        EXPECT_EQ(in.object_to_world[0][3], 1e30f);
        EXPECT_LE(in.world_lo[0], 1e30f);
        EXPECT_GE(in.world_hi[0], 1e30f);
        EXPECT_EQ(in.world_to_object[0][3], -1e30f);
    }
    EXPECT_TRUE(found);
    // 1e38 is beyond it: refused with the node named.
    write_gltf(dir / "beyond.gltf", {box_mesh()}, {{0, ""}, {0, translation(0, 1e38, 0)}});
    const Result r = compile_file(dir / "beyond.gltf", dir / "beyond.cwbvh", 1, false, stats);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message.find("glTF node 1"), std::string::npos) << r.message;
    // 1e39 is beyond float itself (checked before the conversion, which would be UB).
    write_gltf(dir / "inf.gltf", {box_mesh()}, {{0, ""}, {0, translation(1e39, 0, 0)}});
    const Result q = compile_file(dir / "inf.gltf", dir / "inf.cwbvh", 1, false, stats);
    ASSERT_FALSE(q.ok());
    EXPECT_NE(q.message.find("beyond float range"), std::string::npos) << q.message;
}

TEST(TwoLevel, CoreWithOnePlacementGivesATopLevelOfOneLeaf) {
    // compile_two_level straight from the core: one mesh, one placement.
    InstancedScene scene;
    Scene mesh;
    mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    mesh.indices = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    for (uint32_t t = 0; t < 4; ++t) mesh.sources.push_back(SourceRef{0, 7, 0, t});
    mesh.input_names = {"core"};
    scene.meshes.push_back(mesh);
    scene.source_mesh = {7};
    Placement p;
    p.source_node = 3;
    p.object_to_world = {0, -1, 0, 5, 1, 0, 0, 6, 0, 0, 1, 7};
    scene.placements = {p};
    scene.input_names = {"core"};
    TwoLevelResult result;
    ASSERT_TRUE(compile_two_level(scene, CoreOptions{}, "core", result).ok());
    const fs::path dir = test::temp_dir("two_level_core");
    std::vector<std::pair<std::string, uint64_t>> bytes;
    uint64_t file_bytes = 0;
    ASSERT_TRUE(write_two_level(result, (dir / "c.cwbvh").string(), bytes, file_bytes).ok());
    const Parsed f = parse(dir / "c.cwbvh");
    check_two_level(f);
    EXPECT_EQ(f.array<CwbvhNode>(kSectionTopNodes).size(), 1u);
    const auto insts = f.array<InstanceRecord>(kSectionInstances);
    ASSERT_EQ(insts.size(), 1u);
    EXPECT_EQ(insts[0].source_node, 3u);
    EXPECT_EQ(insts[0].world_to_object[0][1], 1.0f);  // the inverse of a quarter turn
    EXPECT_EQ(f.array<MeshRecord>(kSectionMeshes)[0].source_mesh, 7u);
}

TEST(TwoLevel, WorldBoxHoldsWhatTheFloatInverseMapsIntoTheMeshBox) {
    // The traversal moves world points with the float world_to_object
    // (transform.h). Every world point it maps into the mesh box must lie in
    // the world box, or the TLAS culls a hit. For random transforms (one axis
    // scaled by 2^0..2^-17, translations up to 1e5), walk outward float by
    // float from each corner's image along each axis: while the moved point
    // lands in the mesh box it must lie in the world box. The bad case: the
    // tight box of the corners alone (computed here) fails this for some of
    // them, so the walk can see the error the widening covers.
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    MeshRecord mesh{};
    for (int a = 0; a < 3; ++a) {
        mesh.lo[a] = -1.0f;
        mesh.hi[a] = 1.0f;
    }
    int tried = 0, tight_bad = 0, points = 0;
    for (int it = 0; it < 400; ++it) {
        Placement p;
        const double thin = std::ldexp(1.0, -(it % 18)), move = std::pow(10.0, 1 + it % 5);
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) p.object_to_world[size_t(4 * r + c)] = u(rng) * (c == it % 3 ? thin : 1.0);
            p.object_to_world[size_t(4 * r + 3)] = move * u(rng);
        }
        InstanceRecord rec;
        if (!make_instance_record(p, mesh, rec).ok()) continue;  // condition number above 2^20
        ++tried;
        float tight_lo[3], tight_hi[3];
        for (int r = 0; r < 3; ++r) {
            double lo = 1e300, hi = -1e300;
            for (int k = 0; k < 8; ++k) {
                double v = rec.object_to_world[r][3];
                for (int c = 0; c < 3; ++c) v += double(rec.object_to_world[r][c]) * (((k >> c) & 1) ? 1.0 : -1.0);
                lo = std::min(lo, v);
                hi = std::max(hi, v);
            }
            tight_lo[r] = float(lo) > lo ? next_float_down(float(lo)) : float(lo);
            tight_hi[r] = float(hi) < hi ? next_float_up(float(hi)) : float(hi);
        }
        bool tight_failed = false;
        for (int k = 0; k < 8; ++k) {
            const float corner[3] = {(k & 1) ? 1.0f : -1.0f, (k & 2) ? 1.0f : -1.0f, (k & 4) ? 1.0f : -1.0f};
            float w[3];
            transform_point(rec.object_to_world, corner, w);
            for (int axis = 0; axis < 3; ++axis)
                for (int dir = -1; dir <= 1; dir += 2) {
                    float x[3] = {w[0], w[1], w[2]};
                    for (int step = 0; step < 64; ++step) {
                        x[axis] = dir > 0 ? next_float_up(x[axis]) : next_float_down(x[axis]);
                        float o[3];
                        transform_point(rec.world_to_object, x, o);
                        bool in = true;
                        for (int a = 0; a < 3; ++a) in = in && o[a] >= mesh.lo[a] && o[a] <= mesh.hi[a];
                        if (!in) continue;
                        ++points;
                        tight_failed = tight_failed || !(x[axis] >= tight_lo[axis] && x[axis] <= tight_hi[axis]);
                        ASSERT_TRUE(x[axis] >= rec.world_lo[axis] && x[axis] <= rec.world_hi[axis])
                            << "transform " << it << " corner " << k << " axis " << axis << " step " << step;
                    }
                }
        }
        tight_bad += tight_failed;
    }
    EXPECT_GT(tried, 300);
    EXPECT_GT(points, 0);
    EXPECT_GT(tight_bad, 0) << "the tight box never failed: the walk would not see a missing widening";
}

TEST(TwoLevel, InstanceRecordRoundsTheWorldBoxOutward) {
    // A rotation by 30 degrees: the corners land between floats; the box
    // must contain the exact (double) image of every corner.
    Placement p;
    const double c = std::cos(0.5235987755982988), s = std::sin(0.5235987755982988);
    p.object_to_world = {c, -s, 0, 0.1, s, c, 0, 0.2, 0, 0, 1, 0.3};
    MeshRecord mesh{};
    for (int a = 0; a < 3; ++a) {
        mesh.lo[a] = -0.7f;
        mesh.hi[a] = 1.3f;
    }
    InstanceRecord rec;
    ASSERT_TRUE(make_instance_record(p, mesh, rec).ok());
    for (int k = 0; k < 8; ++k) {
        const double v[3] = {(k & 1) ? 1.3f : -0.7f, (k & 2) ? 1.3f : -0.7f, (k & 4) ? 1.3f : -0.7f};
        for (int r = 0; r < 3; ++r) {
            const double w = double(rec.object_to_world[r][0]) * v[0] + double(rec.object_to_world[r][1]) * v[1] +
                             double(rec.object_to_world[r][2]) * v[2] + double(rec.object_to_world[r][3]);
            EXPECT_LT(double(rec.world_lo[r]), w);
            EXPECT_GT(double(rec.world_hi[r]), w);
        }
    }
    // A singular matrix (a zero column) and a far too thin one are refused.
    Placement flat = p;
    flat.object_to_world[2] = flat.object_to_world[6] = flat.object_to_world[10] = 0.0;
    EXPECT_FALSE(make_instance_record(flat, mesh, rec).ok());
    Placement thin = p;
    thin.object_to_world[10] = 0x1p-21;
    const Result r = make_instance_record(thin, mesh, rec);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message.find("condition number"), std::string::npos) << r.message;
}

}  // namespace
}  // namespace cwbvh::compiler
