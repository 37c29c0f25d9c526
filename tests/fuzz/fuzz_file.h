// Shared by the fuzz targets that start from a whole .cwbvh file (fuzz_validate.cpp,
// fuzz_trace.cpp): resealing mutated bytes, and copying a section out of them.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <vector>

#include "cwbvh/format/checksum.h"
#include "cwbvh/format/deep_check.h"
#include "cwbvh/format/source_map.h"
#include "cwbvh/format/validate.h"

namespace cwbvh::fuzz {

/// Recomputes the meta checksum and every in-range payload checksum of `f` in place.
/// Random mutations almost never keep the checksums right, which would stop a fuzzer at
/// rule 3005; resealed, a mutation reaches the table and content rules.
inline void reseal(std::vector<uint8_t>& f) {
    if (f.size() < sizeof(FileHeader)) return;
    FileHeader h;
    std::memcpy(&h, f.data(), sizeof h);
    const uint64_t size = f.size();
    if (h.section_table_offset > size || uint64_t(h.section_count) * sizeof(SectionEntry) > size - h.section_table_offset)
        return;
    for (uint32_t i = 0; i < h.section_count; ++i) {
        SectionEntry e;
        uint8_t* at = f.data() + h.section_table_offset + uint64_t(i) * sizeof e;
        std::memcpy(&e, at, sizeof e);
        if (e.offset <= size && e.size <= size - e.offset) {
            e.checksum = payload_checksum(f.data() + e.offset, e.size);
            std::memcpy(at, &e, sizeof e);
        }
    }
    h.meta_checksum = meta_checksum(h, f.data() + h.section_table_offset, h.section_count * sizeof(SectionEntry));
    std::memcpy(f.data(), &h, sizeof h);
}

/// The records of section `type` of a file that passed validate() (empty when the file has
/// none), copied: the payloads are not aligned for the structs in a fuzzer's buffer.
template <class T>
std::vector<T> section_copy(const FileLayout& layout, uint32_t type) {
    std::vector<T> out;
    const SectionEntry* e = layout.find(type);
    out.resize(e ? e->element_count : 0);
    if (!out.empty()) std::memcpy(out.data(), layout.payload(*e).data(), out.size() * sizeof(T));
    return out;
}

/// Every section a reader traces or checks, copied out of a file that passed validate().
struct FileSections {
    std::vector<CwbvhNode> nodes, top;
    std::vector<TriangleRecord> tris;
    std::vector<SourceRange> ranges;
    std::vector<Bvh2Node> bvh2, bv2l;
    std::vector<MeshRecord> meshes;
    std::vector<InstanceRecord> instances;
    std::vector<SceneBounds> bounds;
    uint64_t stored = 0;  ///< PMAP total: the stored triangle count

    explicit FileSections(const FileLayout& layout)
        : nodes(section_copy<CwbvhNode>(layout, kSectionNodes)),
          top(section_copy<CwbvhNode>(layout, kSectionTopNodes)),
          tris(section_copy<TriangleRecord>(layout, kSectionTriangles)),
          ranges(section_copy<SourceRange>(layout, kSectionSourceMap)),
          bvh2(section_copy<Bvh2Node>(layout, kSectionBvh2)),
          bv2l(section_copy<Bvh2Node>(layout, kSectionBvh2Leaves)),
          meshes(section_copy<MeshRecord>(layout, kSectionMeshes)),
          instances(section_copy<InstanceRecord>(layout, kSectionInstances)),
          bounds(section_copy<SceneBounds>(layout, kSectionBounds)),
          stored(source_range_total(ranges)) {}

    bool two_level() const { return !meshes.empty(); }

    /// Whether some stored triangle has more than one TRIS record (spatial splits).
    /// (Sorted copies of the prims: nothing is sized by the file's PMAP total.)
    bool has_split_triangles() const {
        std::vector<uint32_t> prims;
        prims.reserve(tris.size());
        for (const TriangleRecord& t : tris) prims.push_back(t.prim);
        std::sort(prims.begin(), prims.end());
        return std::adjacent_find(prims.begin(), prims.end()) != prims.end();
    }

    /// Runs every deep check that applies (D1-D7); true when all pass. They size tables by
    /// counts from the file (the PMAP total: issue 21 finding 1), so they are fuzzed too.
    bool deep_checks_pass() const {
        bool ok = deep_check(nodes, tris, stored).ok();
        if (!bvh2.empty()) ok = deep_check_bvh2(bvh2, false, tris, stored).ok() && ok;
        if (!bv2l.empty()) ok = deep_check_bvh2(bv2l, true, tris, stored).ok() && ok;
        if (two_level())
            ok = deep_check_two_level(tris, {meshes, instances, top, bounds.empty() ? nullptr : bounds.data()}).ok() && ok;
        return ok;
    }
};

}  // namespace cwbvh::fuzz
