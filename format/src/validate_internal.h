// Per-section content checks used by validate.cpp. Each gets the payload of a
// structurally valid entry (size == element_size * count, inside the file).
#pragma once

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/format/validate.h"

namespace cwbvh::detail {

/// Element i of a payload, copied out (the buffer may be unaligned).
template <class T>
T load(std::span<const uint8_t> payload, uint64_t i) {
    T v;
    std::memcpy(&v, payload.data() + i * sizeof(T), sizeof(T));
    return v;
}


uint64_t count_of(const FileLayout& layout, uint32_t type);  ///< 0 if absent

/// Stored triangles = first + count of the last PMAP range (0 if PMAP is
/// absent or empty); read from the payload whether or not PMAP was selected.
uint64_t stored_triangle_count(const FileLayout& layout);

Result check_nodes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);
Result check_triangles(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);
Result check_source_map(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);
Result check_bounds(std::span<const uint8_t> payload);
Result check_build_info(std::span<const uint8_t> payload);
/// BVH2 (leaf_ranges false) or BV2L (true): the same record, rules 5601-5609.
Result check_bvh2(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count, bool leaf_ranges);
Result check_vertices(std::span<const uint8_t> payload, uint64_t count);
Result check_indices(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);
Result check_source_names(std::span<const uint8_t> payload);
// Two-level sections (spec 3.9-3.11).
/// MESH's records with the tiling rules 6002-6004 checked (empty if MESH is absent).
Result load_mesh_ranges(const FileLayout& layout, std::vector<MeshRecord>& meshes);
Result check_meshes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);
Result check_instances(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);
/// TLAS: rules 61xx (the NODE rules + 1000, INST as leaf records) and 6041.
Result check_top_nodes(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count);

}  // namespace cwbvh::detail
