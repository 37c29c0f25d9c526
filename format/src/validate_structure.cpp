// Header and section-table rules (spec: "Validation rules" 2xxx-4xxx).
// Every range is checked as `offset <= size && len <= size - offset` and every
// product with __builtin_mul_overflow before any byte it covers is read.
#include <algorithm>
#include <bit>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "cwbvh/format/checksum.h"
#include "cwbvh/format/hex.h"
#include "cwbvh/format/validate.h"

namespace cwbvh {
namespace {

static_assert(std::endian::native == std::endian::little,
              "the format is little-endian; a big-endian reader must byte-swap");

using std::to_string;

bool in_file(uint64_t offset, uint64_t len, uint64_t size) { return offset <= size && len <= size - offset; }

/// [a, a+alen) and [b, b+blen) share a byte (empty ranges share nothing).
bool overlaps(uint64_t a, uint64_t alen, uint64_t b, uint64_t blen) {
    return alen != 0 && blen != 0 && a < b + blen && b < a + alen;
}

/// A hint for the common ways a transfer damages the magic (spec: "Magic").
std::string magic_hint(std::span<const uint8_t> f) {
    if (f.size() >= 1 && f[0] == 0x2B && f.size() >= 6 && std::memcmp(f.data() + 1, "CWBVH", 5) == 0)
        return " (high bit stripped: 7-bit transfer?)";
    if (f.size() >= 10 && std::memcmp(f.data(), kMagic, 7) == 0 && f[7] == 0x0A && f[8] == 0x1A)
        return " (CR LF became LF: text-mode transfer?)";
    if (f.size() >= 12 && std::memcmp(f.data(), kMagic, 10) == 0 && f[10] == 0x0D)
        return " (LF became CR LF: text-mode transfer?)";
    return "";
}

Result check_header(std::span<const uint8_t> f, FileHeader& h) {
    const size_t size = f.size();
    if (size == 0) return fail(rule::kTruncatedHeader, "header: file is empty");
    if (std::memcmp(f.data(), kMagic, std::min<size_t>(size, sizeof kMagic)) != 0)
        return fail(rule::kBadMagic, "header: not a cwbvh file: wrong magic" + magic_hint(f));
    if (size < sizeof(FileHeader))
        return fail(rule::kTruncatedHeader,
                    "header: file is " + to_string(size) + " bytes, shorter than the 64-byte header (truncated)");
    std::memcpy(&h, f.data(), sizeof h);
    if (h.version_major != kVersionMajor)
        return fail(rule::kUnsupportedMajor, "header: unsupported version " + to_string(h.version_major) + "." +
                                                 to_string(h.version_minor) + " (this reader knows major " +
                                                 to_string(kVersionMajor) + ")");
    if (h.header_size != sizeof(FileHeader))
        return fail(rule::kHeaderSize, "header: header_size is " + to_string(h.header_size) + ", must be 64");
    if (h.file_size != size)
        return fail(rule::kFileSize, "header: file_size says " + to_string(h.file_size) + " bytes but the file has " +
                                         to_string(size) + (h.file_size > size ? " (truncated)" : " (trailing bytes)"));
    if (h.section_table_offset % 8 != 0 || h.section_table_offset < sizeof(FileHeader))
        return fail(rule::kTableAlignment, "header: section_table_offset " + to_string(h.section_table_offset) +
                                               " is not a multiple of 8 at or after byte 64");
    uint64_t table_bytes = 0;
    if (__builtin_mul_overflow(uint64_t(h.section_count), uint64_t(sizeof(SectionEntry)), &table_bytes) ||
        !in_file(h.section_table_offset, table_bytes, size))
        return fail(rule::kTableOutsideFile, "header: section table (" + to_string(h.section_count) +
                                                 " entries at offset " + to_string(h.section_table_offset) +
                                                 ") extends past the end of the file");
    const uint64_t sum = meta_checksum(h, f.data() + h.section_table_offset, table_bytes);
    if (sum != h.meta_checksum)
        return fail(rule::kMetaChecksum, "header: meta_checksum mismatch (header or section table damaged)");
    if (h.flags != 0) return fail(rule::kHeaderFlags, "header: flags must be 0, is " + to_string(h.flags));
    if (h.reserved0 != 0 || h.reserved1 != 0) return fail(rule::kHeaderReserved, "header: reserved fields must be 0");
    return Result::success();
}

Result check_entry(const SectionEntry& e, const FileHeader& h, uint64_t size) {
    const std::string name = "section " + section_name(e.type);
    const SectionInfo* info = find_section_info(e.type);
    if ((e.flags & ~uint32_t(kSectionRequired)) != 0)
        return fail(rule::kSectionFlags, name + ": unknown flag bits " + hex32(e.flags));
    if (e.reserved != 0) return fail(rule::kSectionReserved, name + ": reserved field must be 0");
    if (info == nullptr && (e.flags & kSectionRequired) != 0)
        return fail(rule::kUnknownRequiredSection, name + ": unknown section type marked required");
    if (info != nullptr && e.element_size != info->element_size)
        return fail(rule::kElementSize, name + ": element_size is " + to_string(e.element_size) + ", must be " +
                                            to_string(info->element_size));
    uint64_t bytes = 0;
    if (e.element_size == 0 || __builtin_mul_overflow(uint64_t(e.element_size), e.element_count, &bytes) ||
        bytes != e.size)
        return fail(rule::kSectionSize, name + ": size " + to_string(e.size) + " is not element_size " +
                                            to_string(e.element_size) + " x element_count " +
                                            to_string(e.element_count));
    if (e.offset % kSectionAlignment != 0)
        return fail(rule::kSectionAlignment, name + ": offset " + to_string(e.offset) + " is not a multiple of 64");
    if (!in_file(e.offset, e.size, size))
        return fail(rule::kSectionOutsideFile, name + ": bytes " + to_string(e.offset) + "+" + to_string(e.size) +
                                                   " extend past the end of the file (" + to_string(size) + " bytes)");
    if (overlaps(e.offset, e.size, 0, sizeof(FileHeader)) ||
        overlaps(e.offset, e.size, h.section_table_offset, uint64_t(h.section_count) * sizeof(SectionEntry)))
        return fail(rule::kSectionOverlapsHeader, name + ": overlaps the header or the section table");
    return Result::success();
}

Result check_counts(const FileLayout& layout) {
    auto count = [&](uint32_t type) -> const SectionEntry* { return layout.find(type); };
    for (const SectionInfo& info : kKnownSections)
        if (info.mandatory && count(info.type) == nullptr)
            return fail(rule::kMissingSection, "section " + section_name(info.type) + ": missing (mandatory)");
    auto bad = [](uint32_t type, const std::string& what) {
        return fail(rule::kElementCount, "section " + section_name(type) + ": " + what);
    };
    const SectionEntry* nodes = count(kSectionNodes);
    if (nodes->element_count == 0) return bad(kSectionNodes, "no nodes (the root, node 0, is required)");
    if (nodes->element_count > 0xFFFFFFFFu) return bad(kSectionNodes, "more than 2^32-1 nodes");
    if (count(kSectionTriangles)->element_count > 0xFFFFFFFFu) return bad(kSectionTriangles, "more than 2^32-1 records");
    if (count(kSectionSourceMap)->element_count > 0x100000000u) return bad(kSectionSourceMap, "more than 2^32 entries");
    if (count(kSectionBounds)->element_count != 1) return bad(kSectionBounds, "must hold exactly 1 element");
    if (const SectionEntry* e = count(kSectionBuildInfo); e && e->element_count != 1)
        return bad(kSectionBuildInfo, "must hold exactly 1 element");
    for (const uint32_t type : {kSectionBvh2, kSectionBvh2Leaves}) {
        const SectionEntry* e = count(type);
        if (e == nullptr) continue;
        if (e->element_count == 0) return bad(type, "present but empty (the root, node 0, is required)");
        if (e->element_count > 0x7FFFFFFFu) return bad(type, "more than 2^31-1 nodes");
        if (count(kSectionTriangles)->element_count > 0x80000000u)
            return bad(type, "TRIS has more records than a binary BVH leaf index can address");
        // BV2L: a traversal packs (first record << 2 | count - 1) into 31 bits (spec 4).
        if (type == kSectionBvh2Leaves && count(kSectionTriangles)->element_count > kMaxBvh2LeafTris)
            return bad(type, "TRIS has more than 2^29 records (the limit of a file with leaf ranges)");
    }
    if (const SectionEntry* e = count(kSectionVertices); e && e->element_count > 0x100000000u)
        return bad(kSectionVertices, "more than 2^32 vertices");
    // Two-level sections (spec 3.9): all three or none, never with a binary BVH over TRIS.
    const int two_level = int(count(kSectionMeshes) != nullptr) + int(count(kSectionInstances) != nullptr) +
                          int(count(kSectionTopNodes) != nullptr);
    if (two_level != 0 && two_level != 3)
        return fail(rule::kTwoLevelSections, "two-level file: MESH, INST and TLAS must all be present (found " +
                                                 to_string(two_level) + " of the 3)");
    if (two_level == 3) {
        for (const uint32_t type : {kSectionMeshes, kSectionInstances, kSectionTopNodes}) {
            if (count(type)->element_count == 0) return bad(type, "a two-level file needs at least 1 element");
            if (count(type)->element_count > 0xFFFFFFFFu) return bad(type, "more than 2^32-1 elements");
        }
        for (const uint32_t type : {kSectionBvh2, kSectionBvh2Leaves})
            if (count(type) != nullptr)
                return fail(rule::kTwoLevelSections, "section " + section_name(type) +
                                                         ": not allowed in a two-level file (it would span the "
                                                         "meshes' object spaces as one)");
    }
    // INDX's count is checked against the PMAP total by its content rule (5802).
    if (count(kSectionIndices) != nullptr && count(kSectionVertices) == nullptr)
        return fail(rule::kMissingSection, "section INDX: present without VERT");
    return Result::success();
}

/// Sections must not overlap each other; every byte not in the header, the
/// table or a section must be zero.
Result check_overlap_and_padding(const FileLayout& layout) {
    struct Range {
        uint64_t begin, size;
        uint32_t type;
    };
    std::vector<Range> ranges;
    ranges.push_back({0, sizeof(FileHeader), 0});
    ranges.push_back({layout.header.section_table_offset,
                      uint64_t(layout.header.section_count) * sizeof(SectionEntry), 0});
    for (const SectionEntry& e : layout.table)
        if (e.size != 0) ranges.push_back({e.offset, e.size, e.type});
    std::sort(ranges.begin(), ranges.end(), [](const Range& a, const Range& b) { return a.begin < b.begin; });
    uint64_t cursor = 0;
    uint32_t prev_type = 0;
    const std::span<const uint8_t> f = layout.file;
    // Where the file must end (spec 2, rule 4015): after the header, the table and every
    // section; a section of size 0 counts with its offset (a writer pads up to it).
    uint64_t end = 0;
    for (const Range& r : ranges) end = std::max(end, r.begin + r.size);
    for (const SectionEntry& e : layout.table) end = std::max(end, e.offset);
    for (const Range& r : ranges) {
        if (r.begin < cursor)
            return fail(rule::kSectionOverlap, "section " + section_name(r.type) + ": overlaps section " +
                                                   section_name(prev_type));
        for (uint64_t i = cursor; i < r.begin; ++i)
            if (f[i] != 0)
                return fail(rule::kNonZeroPadding, "padding: byte " + to_string(i) + " between sections is not zero");
        cursor = r.begin + r.size;
        prev_type = r.type;
    }
    for (uint64_t i = cursor; i < end; ++i)
        if (f[i] != 0) return fail(rule::kNonZeroPadding, "padding: byte " + to_string(i) + " between sections is not zero");
    if (f.size() > end)
        return fail(rule::kTrailingBytes, "layout: " + to_string(f.size() - end) + " bytes after the end of the last "
                                          "section (byte " + to_string(end) + "); the format has no padding there");
    return Result::success();
}

}  // namespace

const SectionEntry* FileLayout::find(uint32_t type) const {
    for (const SectionEntry& e : table)
        if (e.type == type) return &e;
    return nullptr;
}

std::span<const uint8_t> FileLayout::payload(const SectionEntry& entry) const {
    return file.subspan(entry.offset, entry.size);
}

Result validate_structure(std::span<const uint8_t> file, FileLayout& layout) {
    layout = FileLayout{};
    layout.file = file;
    if (Result r = check_header(file, layout.header); !r.ok()) return r;
    const FileHeader& h = layout.header;
    layout.table.resize(h.section_count);
    if (h.section_count != 0)
        std::memcpy(layout.table.data(), file.data() + h.section_table_offset, h.section_count * sizeof(SectionEntry));
    for (const SectionEntry& e : layout.table)
        if (Result r = check_entry(e, h, file.size()); !r.ok()) return r;
    std::vector<uint32_t> types;
    for (const SectionEntry& e : layout.table) types.push_back(e.type);
    std::sort(types.begin(), types.end());
    if (auto dup = std::adjacent_find(types.begin(), types.end()); dup != types.end())
        return fail(rule::kDuplicateSection, "section " + section_name(*dup) + ": appears more than once");
    if (Result r = check_counts(layout); !r.ok()) return r;
    return check_overlap_and_padding(layout);
}

}  // namespace cwbvh
