// libFuzzer target for cwbvh::validate. Random mutations almost never keep
// the meta checksum right, which would stop the fuzzer at rule 3005; so for
// half of the inputs the harness first "reseals" a copy (recomputes the meta
// and payload checksums wherever the fields are in range), which lets it
// reach the table and content rules. The other half is validated as is. A
// file that passes is walked, and the deep checks (D1-D6) run on it: they size
// tables by counts from the file (the PMAP total: issue 21 finding 1).
#include <cstdint>
#include <cstring>
#include <vector>

#include "cwbvh/format/checksum.h"
#include "cwbvh/format/deep_check.h"
#include "cwbvh/format/source_map.h"
#include "cwbvh/format/validate.h"

namespace {

void reseal(std::vector<uint8_t>& f) {
    using namespace cwbvh;
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

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    cwbvh::ValidateOptions options;
    options.verify_checksums = size % 3 != 0;
    if (size % 2 == 0) {
        (void)cwbvh::validate({data, size}, options);
        return 0;
    }
    std::vector<uint8_t> copy(data, data + size);
    reseal(copy);
    cwbvh::FileLayout layout;
    const cwbvh::Result r = cwbvh::validate(copy, options, &layout);
    if (r.ok()) {
        // A file that passes must be safe to walk: touch every section's bytes.
        volatile uint8_t sink = 0;
        for (const cwbvh::SectionEntry& e : layout.table)
            for (uint8_t b : layout.payload(e)) sink = sink ^ b;
        // Copies: the payloads are not aligned for the structs in the fuzzer's buffer.
        auto section = [&]<class T>(uint32_t type, std::vector<T>& out) {
            const cwbvh::SectionEntry* e = layout.find(type);
            out.resize(e ? e->element_count : 0);
            if (!out.empty()) std::memcpy(out.data(), layout.payload(*e).data(), out.size() * sizeof(T));
        };
        std::vector<cwbvh::CwbvhNode> nodes;
        std::vector<cwbvh::TriangleRecord> tris;
        std::vector<cwbvh::SourceRange> ranges;
        std::vector<cwbvh::Bvh2Node> bvh2, bv2l;
        section(cwbvh::kSectionNodes, nodes);
        section(cwbvh::kSectionTriangles, tris);
        section(cwbvh::kSectionSourceMap, ranges);
        section(cwbvh::kSectionBvh2, bvh2);
        section(cwbvh::kSectionBvh2Leaves, bv2l);
        const uint64_t stored = cwbvh::source_range_total(ranges);
        (void)cwbvh::deep_check(nodes, tris, stored);
        if (!bvh2.empty()) (void)cwbvh::deep_check_bvh2(bvh2, false, tris, stored);
        if (!bv2l.empty()) (void)cwbvh::deep_check_bvh2(bv2l, true, tris, stored);
        // Two-level files (format 1.2): D7 over MESH, INST, TLAS and BNDS.
        std::vector<cwbvh::MeshRecord> meshes;
        std::vector<cwbvh::InstanceRecord> instances;
        std::vector<cwbvh::CwbvhNode> top;
        std::vector<cwbvh::SceneBounds> bounds;
        section(cwbvh::kSectionMeshes, meshes);
        section(cwbvh::kSectionInstances, instances);
        section(cwbvh::kSectionTopNodes, top);
        section(cwbvh::kSectionBounds, bounds);
        if (!meshes.empty())
            (void)cwbvh::deep_check_two_level(tris, {meshes, instances, top, bounds.empty() ? nullptr : bounds.data()});
    }
    return 0;
}
