#include "cwbvh/format/sections.h"

namespace cwbvh {

const SectionInfo* find_section_info(uint32_t type) {
    for (const SectionInfo& info : kKnownSections)
        if (info.type == type) return &info;
    return nullptr;
}

std::string section_name(uint32_t type) {
    static const char kHex[] = "0123456789abcdef";
    std::string name;
    for (int i = 0; i < 4; ++i) {
        const auto c = uint8_t(type >> (8 * i));
        if (c >= 0x20 && c < 0x7F && c != '\\') {
            name += char(c);
        } else {
            name += "\\x";
            name += kHex[c >> 4];
            name += kHex[c & 15];
        }
    }
    return name;
}

uint32_t default_section_flags(uint32_t type) {
    const SectionInfo* info = find_section_info(type);
    return info != nullptr && info->required ? uint32_t(kSectionRequired) : 0u;
}

}  // namespace cwbvh
