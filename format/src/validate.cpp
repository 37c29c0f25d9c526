#include "cwbvh/format/validate.h"

#include <cstdio>

#include "cwbvh/format/checksum.h"
#include "validate_internal.h"

namespace cwbvh {
namespace detail {

uint64_t count_of(const FileLayout& layout, uint32_t type) {
    const SectionEntry* e = layout.find(type);
    return e != nullptr ? e->element_count : 0;
}

}  // namespace detail

Result validate_section(const FileLayout& layout, const SectionEntry& entry, bool verify_checksum) {
    using namespace detail;
    const std::span<const uint8_t> payload = layout.payload(entry);
    if (verify_checksum && payload_checksum(payload.data(), payload.size()) != entry.checksum)
        return fail(rule::kSectionChecksum, "section " + section_name(entry.type) + ": checksum mismatch (payload damaged)");
    const uint64_t n = entry.element_count;
    switch (entry.type) {
        case kSectionNodes: return check_nodes(layout, payload, n);
        case kSectionTriangles: return check_triangles(layout, payload, n);
        case kSectionSourceMap: return check_source_map(layout, payload, n);
        case kSectionBounds: return check_bounds(payload);
        case kSectionBuildInfo: return check_build_info(payload);
        case kSectionBvh2: return check_bvh2(layout, payload, n, false);
        case kSectionBvh2Leaves: return check_bvh2(layout, payload, n, true);
        case kSectionVertices: return check_vertices(payload, n);
        case kSectionIndices: return check_indices(layout, payload, n);
        case kSectionSourceNames: return check_source_names(payload);
        case kSectionMeshes: return check_meshes(layout, payload, n);
        case kSectionInstances: return check_instances(layout, payload, n);
        case kSectionTopNodes: return check_top_nodes(layout, payload, n);
        default: return Result::success();  // unknown optional section: skipped
    }
}

Result validate(std::span<const uint8_t> file, const ValidateOptions& options, FileLayout* layout) {
    FileLayout local;
    FileLayout& l = layout != nullptr ? *layout : local;
    if (Result r = validate_structure(file, l); !r.ok()) return r;
    // Spec order, so the first error reported does not depend on table order.
    for (const SectionInfo& info : kKnownSections) {
        if ((options.sections & info.mask) == 0) continue;
        if (const SectionEntry* e = l.find(info.type))
            if (Result r = validate_section(l, *e, options.verify_checksums); !r.ok()) return r;
    }
    // Unknown optional sections (spec 2.5): their content is skipped, their checksum is verified
    // by a validation of the whole file (every known section selected), in table order.
    if (options.verify_checksums && (options.sections & kMaskAll) == kMaskAll)
        for (const SectionEntry& e : l.table)
            if (find_section_info(e.type) == nullptr)
                if (Result r = validate_section(l, e, true); !r.ok()) return r;
    return Result::success();
}

}  // namespace cwbvh
