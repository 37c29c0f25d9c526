#include "cwbvh/format/writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "cwbvh/format/checksum.h"
#include "cwbvh/format/sections.h"

namespace cwbvh {
namespace {

uint64_t align_up(uint64_t v, uint64_t a) { return (v + a - 1) / a * a; }

Result write_all(int fd, const void* data, size_t size, const std::string& path) {
    const auto* p = static_cast<const uint8_t*>(data);
    while (size > 0) {
        const ssize_t n = ::write(fd, p, size);
        if (n < 0) {
            if (errno == EINTR) continue;
            return fail(rule::kWriteFailed, path + ": write failed: " + std::strerror(errno));
        }
        p += n;
        size -= size_t(n);
    }
    return Result::success();
}

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

    static std::atomic<uint64_t> counter{0};
    const std::string tmp = path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) return fail(rule::kOpenFailed, tmp + ": cannot create: " + std::strerror(errno));

    Result r = write_all(fd, &header, sizeof header, tmp);
    if (r.ok()) r = write_all(fd, table.data(), table.size() * sizeof(SectionEntry), tmp);
    uint64_t cursor = sizeof header + table.size() * sizeof(SectionEntry);
    static const uint8_t kZeros[kSectionAlignment] = {};
    for (size_t i = 0; r.ok() && i < table.size(); ++i) {
        r = write_all(fd, kZeros, table[i].offset - cursor, tmp);  // padding < 64 bytes
        if (r.ok()) r = write_all(fd, sections_[i].bytes.data(), table[i].size, tmp);
        cursor = table[i].offset + table[i].size;
    }
    if (::close(fd) != 0 && r.ok()) r = fail(rule::kWriteFailed, tmp + ": close failed: " + std::strerror(errno));
    if (r.ok() && std::rename(tmp.c_str(), path.c_str()) != 0)
        r = fail(rule::kWriteFailed, path + ": cannot rename " + tmp + ": " + std::strerror(errno));
    if (!r.ok()) ::unlink(tmp.c_str());
    return r;
}

}  // namespace cwbvh
