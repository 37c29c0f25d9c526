// Small argument helpers shared by the trace/rays/render verbs.
#pragma once

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace cwbvh::tool {

/// Parses a decimal unsigned integer in [lo, hi]; false on anything else.
inline bool parse_u32(const char* text, uint32_t lo, uint32_t hi, uint32_t& out) {
    if (text == nullptr || *text < '0' || *text > '9') return false;
    char* end = nullptr;
    errno = 0;
    const unsigned long long v = std::strtoull(text, &end, 10);
    if (errno != 0 || *end != '\0' || v < lo || v > hi) return false;
    out = uint32_t(v);
    return true;
}

/// The value of option argv[i] (argv[i + 1]); nullptr when missing.
inline const char* option_value(int argc, char** argv, int& i) { return i + 1 < argc ? argv[++i] : nullptr; }

}  // namespace cwbvh::tool
