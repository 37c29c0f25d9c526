// Content rules of the two-level sections MESH and INST (spec 3.9, 3.10: rules
// 6002-6007, 6021-6025). TLAS and rule 6041: validate_nodes.cpp; 6001 and the
// counts: validate_structure.cpp.
#include <cmath>
#include <string>
#include <vector>

#include "cwbvh/format/transform_host.h"
#include "validate_internal.h"

namespace cwbvh::detail {
namespace {

using std::to_string;

Result mesh_error(uint32_t rule_id, uint64_t m, const std::string& what) {
    return fail(rule_id, "section MESH: mesh " + to_string(m) + ": " + what);
}
Result instance_error(uint32_t rule_id, uint64_t i, const std::string& what) {
    return fail(rule_id, "section INST: instance " + to_string(i) + ": " + what);
}

bool finite_box(const float lo[3], const float hi[3]) {
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(lo[a]) || !std::isfinite(hi[a])) return false;
    return true;
}

/// One tiling rule: `first` must be where the previous range ended, `count` >= 1.
Result check_tile(uint32_t rule_id, uint64_t m, const char* what, uint32_t first, uint32_t count, uint64_t& next) {
    if (count == 0) return mesh_error(rule_id, m, std::string(what) + " count is 0");
    if (first != next)
        return mesh_error(rule_id, m, std::string(what) + " range starts at " + to_string(first) + ", not at " +
                                          to_string(next) + " (meshes tile the section in order)");
    next = uint64_t(first) + count;
    return Result::success();
}

}  // namespace

Result load_mesh_ranges(const FileLayout& layout, std::vector<MeshRecord>& meshes) {
    meshes.clear();
    const SectionEntry* e = layout.find(kSectionMeshes);
    if (e == nullptr) return Result::success();
    // MESH's count is bounded by the file size (64 bytes each, rule 4005).
    const std::span<const uint8_t> payload = layout.payload(*e);
    meshes.resize(e->element_count);
    uint64_t next_node = 0, next_tri = 0, next_prim = 0;
    for (uint64_t m = 0; m < e->element_count; ++m) {
        const MeshRecord r = load<MeshRecord>(payload, m);
        meshes[m] = r;
        if (Result x = check_tile(rule::kMeshNodeRange, m, "node", r.node_first, r.node_count, next_node); !x.ok())
            return x;
        if (Result x = check_tile(rule::kMeshTriRange, m, "TRIS", r.tri_first, r.tri_count, next_tri); !x.ok())
            return x;
        if (Result x = check_tile(rule::kMeshPrimRange, m, "stored triangle", r.prim_first, r.prim_count, next_prim);
            !x.ok())
            return x;
    }
    const uint64_t nodes = count_of(layout, kSectionNodes), tris = count_of(layout, kSectionTriangles);
    const uint64_t stored = stored_triangle_count(layout);
    if (next_node != nodes)
        return fail(rule::kMeshNodeRange, "section MESH: the meshes' node ranges end at " + to_string(next_node) +
                                              ", not at the NODE count " + to_string(nodes));
    if (next_tri != tris)
        return fail(rule::kMeshTriRange, "section MESH: the meshes' TRIS ranges end at " + to_string(next_tri) +
                                             ", not at the TRIS count " + to_string(tris));
    if (next_prim != stored)
        return fail(rule::kMeshPrimRange, "section MESH: the meshes' stored triangle ranges end at " +
                                              to_string(next_prim) + ", not at the stored triangle count " +
                                              to_string(stored) + " (PMAP total)");
    return Result::success();
}

Result check_meshes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    std::vector<MeshRecord> meshes;
    if (Result r = load_mesh_ranges(layout, meshes); !r.ok()) return r;
    const std::span<const uint8_t> tris = layout.payload(*layout.find(kSectionTriangles));
    for (uint64_t m = 0; m < count; ++m) {
        const MeshRecord r = load<MeshRecord>(payload, m);
        if (!finite_box(r.lo, r.hi)) return mesh_error(rule::kMeshBounds, m, "lo/hi are not finite");
        for (int a = 0; a < 3; ++a)
            if (r.lo[a] > r.hi[a]) return mesh_error(rule::kMeshBounds, m, "lo > hi on axis " + to_string(a));
        for (uint32_t v : r.reserved)
            if (v != 0) return mesh_error(rule::kMeshReserved, m, "reserved field is not 0");
        // The ranges tile TRIS (load_mesh_ranges), so every record read here exists.
        for (uint64_t t = r.tri_first; t < uint64_t(r.tri_first) + r.tri_count; ++t) {
            const auto rec = load<TriangleRecord>(tris, t);
            if (rec.prim < r.prim_first || uint64_t(rec.prim) >= uint64_t(r.prim_first) + r.prim_count)
                return mesh_error(rule::kMeshPrim, m, "TRIS record " + to_string(t) + " has prim " +
                                                          to_string(rec.prim) + ", outside the mesh's stored ids " +
                                                          to_string(r.prim_first) + "+" + to_string(r.prim_count));
        }
    }
    return Result::success();
}

Result check_instances(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    const uint64_t meshes = count_of(layout, kSectionMeshes);
    for (uint64_t i = 0; i < count; ++i) {
        const auto r = load<InstanceRecord>(payload, i);
        if (Result x = check_instance_transforms(r.object_to_world, r.world_to_object); !x.ok())
            return instance_error(x.rule, i, x.message);
        if (r.mesh >= meshes)
            return instance_error(rule::kInstMesh, i, "mesh " + to_string(r.mesh) + " is not below MESH count " +
                                                          to_string(meshes));
        if (!finite_box(r.world_lo, r.world_hi))
            return instance_error(rule::kInstWorldBox, i, "world box is not finite");
        for (int a = 0; a < 3; ++a)
            if (r.world_lo[a] > r.world_hi[a])
                return instance_error(rule::kInstWorldBox, i, "world_lo > world_hi on axis " + to_string(a));
    }
    return Result::success();
}

}  // namespace cwbvh::detail
