// Hexadecimal text for messages and reports (host only): validator errors, ray file
// errors, the GPU self-check's differing cases. One home for the four formats.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

namespace cwbvh {

/// "0x%02x".
inline std::string hex8(uint8_t v) {
    char b[8];
    std::snprintf(b, sizeof b, "0x%02x", unsigned(v));
    return b;
}

/// "0x%08x".
inline std::string hex32(uint32_t v) {
    char b[16];
    std::snprintf(b, sizeof b, "0x%08x", unsigned(v));
    return b;
}

/// "0x%016llx".
inline std::string hex64(uint64_t v) {
    char b[24];
    std::snprintf(b, sizeof b, "0x%016llx", static_cast<unsigned long long>(v));
    return b;
}

/// The n bytes at p in memory order, two lowercase digits each, no prefix or separator.
inline std::string hex_bytes(const void* p, size_t n) {
    static const char kDigits[] = "0123456789abcdef";
    std::string s(2 * n, '0');
    const auto* b = static_cast<const unsigned char*>(p);
    for (size_t i = 0; i < n; ++i) {
        s[2 * i] = kDigits[b[i] >> 4];
        s[2 * i + 1] = kDigits[b[i] & 15];
    }
    return s;
}

}  // namespace cwbvh
