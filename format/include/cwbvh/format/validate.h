// Validation of a .cwbvh file held in memory (an mmap or a buffer). Safe on
// untrusted bytes: every offset, size, count and multiplication is checked
// before anything is read, and no input can cause UB or a crash.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/format/sections.h"
#include "cwbvh/format/status.h"

namespace cwbvh {

struct ValidateOptions {
    /// Verify XXH3-64 payload checksums of the selected sections. The header
    /// and table checksum (meta_checksum) is always verified.
    bool verify_checksums = true;
    /// Known sections (SectionMask bits) whose payload is checked. Header and
    /// section-table checks always run on every entry; unselected sections'
    /// payloads are neither checksummed nor inspected.
    uint32_t sections = kMaskAll;
};

/// The header and table of a file that passed validation, plus the bytes.
struct FileLayout {
    FileHeader header{};
    std::vector<SectionEntry> table;  ///< every entry, in table order (unknown ones too)
    std::span<const uint8_t> file;    ///< the whole file

    /// The entry of a section type, or nullptr.
    const SectionEntry* find(uint32_t type) const;
    /// The payload bytes of an entry of this layout.
    std::span<const uint8_t> payload(const SectionEntry& entry) const;
};

/// Validates `file` (the complete file contents). On success fills `layout`
/// (if non-null). On failure returns the first violated rule; the message
/// names the section and what is wrong, but not the file (callers prefix it).
[[nodiscard]] Result validate(std::span<const uint8_t> file, const ValidateOptions& options = {},
                              FileLayout* layout = nullptr);

/// Header and section-table rules only (2xxx, 3xxx, 4xxx except checksums).
[[nodiscard]] Result validate_structure(std::span<const uint8_t> file, FileLayout& layout);

/// Payload checksum and content rules (4014, 5xxx) of one known section of a
/// structurally valid layout.
[[nodiscard]] Result validate_section(const FileLayout& layout, const SectionEntry& entry,
                                      bool verify_checksum);

}  // namespace cwbvh
