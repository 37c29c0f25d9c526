#include "cwbvh/format/writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "cwbvh/format/checksum.h"
#include "cwbvh/format/file_io.h"
#include "cwbvh/format/sections.h"

namespace cwbvh {
namespace {

uint64_t align_up(uint64_t v, uint64_t a) { return (v + a - 1) / a * a; }


}  // namespace

void Writer::add_section(uint32_t type, uint32_t flags, uint32_t element_size,
                         uint64_t element_count, std::span<const uint8_t> bytes) {
    sections_.push_back({type, flags, element_size, element_count, bytes});
}

Result Writer::layout(FileHeader& header, std::vector<SectionEntry>& table) const {
    table.clear();
    for (size_t i = 0; i < sections_.size(); ++i) {
        const Pending& s = sections_[i];
        const std::string name = "section " + section_name(s.type);
        for (size_t j = 0; j < i; ++j)
            if (sections_[j].type == s.type)
                return Result::fail(Status::kInvalidArgument, rule::kDuplicateSection, name + ": added twice");
        if ((s.flags & ~uint32_t(kSectionRequired)) != 0)
            return Result::fail(Status::kInvalidArgument, rule::kSectionFlags, name + ": unknown flag bits");
        if (s.element_size == 0)
            return Result::fail(Status::kInvalidArgument, rule::kSectionSize, name + ": element size 0");
        uint64_t size = 0;
        if (__builtin_mul_overflow(uint64_t(s.element_size), s.element_count, &size) || size != s.bytes.size())
            return Result::fail(Status::kInvalidArgument, rule::kSectionSize,
                                name + ": " + std::to_string(s.bytes.size()) + " bytes given, element size " +
                                    std::to_string(s.element_size) + " x count " + std::to_string(s.element_count));
        if (const SectionInfo* info = find_section_info(s.type); info && info->element_size != s.element_size)
            return Result::fail(Status::kInvalidArgument, rule::kElementSize,
                                name + ": element size must be " + std::to_string(info->element_size));
    }
    std::memset(&header, 0, sizeof header);
    std::memcpy(header.magic, kMagic, sizeof kMagic);
    header.version_major = kVersionMajor;
    // The lowest minor that covers every known section written (spec 2.2): a file
    // without 1.1 sections stays 1.0, byte for byte what a 1.0 writer made.
    header.version_minor = 0;
    for (const Pending& s : sections_)
        if (const SectionInfo* info = find_section_info(s.type); info && info->since_minor > header.version_minor)
            header.version_minor = info->since_minor;
    header.header_size = sizeof(FileHeader);
    header.section_count = uint32_t(sections_.size());
    header.section_table_offset = sizeof(FileHeader);
    uint64_t cursor = sizeof(FileHeader) + sections_.size() * sizeof(SectionEntry);
    for (const Pending& s : sections_) {
        SectionEntry e{};
        e.type = s.type;
        e.flags = s.flags;
        e.offset = align_up(cursor, kSectionAlignment);
        e.size = s.bytes.size();
        e.element_size = s.element_size;
        e.element_count = s.element_count;
        e.checksum = payload_checksum(s.bytes.data(), s.bytes.size());
        table.push_back(e);
        cursor = e.offset + e.size;
    }
    header.file_size = cursor;
    header.meta_checksum = meta_checksum(header, table.data(), table.size() * sizeof(SectionEntry));
    return Result::success();
}

Result Writer::to_bytes(std::vector<uint8_t>& out) const {
    FileHeader header;
    std::vector<SectionEntry> table;
    if (Result r = layout(header, table); !r.ok()) return r;
    out.assign(header.file_size, 0);
    std::memcpy(out.data(), &header, sizeof header);
    if (!table.empty()) std::memcpy(out.data() + sizeof header, table.data(), table.size() * sizeof(SectionEntry));
    for (size_t i = 0; i < table.size(); ++i)
        if (table[i].size != 0) std::memcpy(out.data() + table[i].offset, sections_[i].bytes.data(), table[i].size);
    return Result::success();
}

Result Writer::write_file(const std::string& path) const {
    FileHeader header;
    std::vector<SectionEntry> table;
    if (Result r = layout(header, table); !r.ok()) return r;
    Expected<AtomicOutput> out = AtomicOutput::create(path);  // the file appears whole or not at all
    if (!out.ok()) return out.error();
    Result r = out->write(&header, sizeof header);
    if (r.ok()) r = out->write(table.data(), table.size() * sizeof(SectionEntry));
    uint64_t cursor = sizeof header + table.size() * sizeof(SectionEntry);
    static const uint8_t kZeros[kSectionAlignment] = {};
    for (size_t i = 0; r.ok() && i < table.size(); ++i) {
        r = out->write(kZeros, table[i].offset - cursor);  // padding < 64 bytes
        if (r.ok()) r = out->write(sections_[i].bytes.data(), table[i].size);
        cursor = table[i].offset + table[i].size;
    }
    return r.ok() ? out->commit() : r;
}

}  // namespace cwbvh
