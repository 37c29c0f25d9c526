// Minimal PNG writer: 8-bit RGB, one IDAT of stored (uncompressed) deflate blocks
// (RFC 1950/1951), CRC-32 per chunk and Adler-32 (PNG spec, ISO/IEC 15948). No
// third-party library.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cwbvh::tool {

/// The PNG file image of `rgb` (width * height * 3 bytes, row 0 at the top).
std::vector<uint8_t> encode_png_rgb(const uint8_t* rgb, uint32_t width, uint32_t height);

/// Writes encode_png_rgb(...) to `path`; false with `error` on an I/O failure.
[[nodiscard]] bool write_png_rgb(const std::string& path, const uint8_t* rgb, uint32_t width, uint32_t height,
                                 std::string& error);

uint32_t crc32(const uint8_t* data, size_t size, uint32_t crc = 0);
uint32_t adler32(const uint8_t* data, size_t size, uint32_t adler = 1);

}  // namespace cwbvh::tool
