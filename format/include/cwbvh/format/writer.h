// Writes a .cwbvh file: header, section table, 64-byte-aligned zero-padded
// payloads and XXH3-64 checksums (spec: "File structure"). Deterministic:
// the same sections in the same order give the same bytes.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"

namespace cwbvh {

class Writer {
public:
    /// Adds a section. The bytes are NOT copied: they must stay alive and
    /// unchanged until the last to_bytes()/write_file() call. Sections are
    /// laid out in the order they are added. Errors (duplicate type, size not
    /// element_size * element_count, unknown flag bits, element_size 0) are
    /// reported by to_bytes()/write_file().
    void add_section(uint32_t type, uint32_t flags, uint32_t element_size,
                     uint64_t element_count, std::span<const uint8_t> bytes);

    /// Typed convenience: element_size = sizeof(T), count = elements.size().
    template <class T>
    void add_array(uint32_t type, uint32_t flags, std::span<const T> elements) {
        add_section(type, flags, uint32_t(sizeof(T)), elements.size(),
                    {reinterpret_cast<const uint8_t*>(elements.data()), elements.size_bytes()});
    }

    /// Header + table for the current sections (checks the sections first).
    [[nodiscard]] Result layout(FileHeader& header, std::vector<SectionEntry>& table) const;

    /// The whole file in memory.
    [[nodiscard]] Result to_bytes(std::vector<uint8_t>& out) const;

    /// Writes `path` atomically: a temporary file in the same directory,
    /// then rename(2). On failure the temporary is removed and `path` is untouched.
    [[nodiscard]] Result write_file(const std::string& path) const;

private:
    struct Pending {
        uint32_t type;
        uint32_t flags;
        uint32_t element_size;
        uint64_t element_count;
        std::span<const uint8_t> bytes;
    };
    std::vector<Pending> sections_;
};

}  // namespace cwbvh
