// PNG output of `cwbvh render`: 8-bit RGB through libpng (png_write.cpp) with fixed
// compression settings, so the same pixels give the same bytes. Built without libpng
// (the GPU-only configuration), png_write_stub.cpp reports that instead.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cwbvh::tool {

/// The PNG file image of `rgb` (width * height * 3 bytes, row 0 at the top); empty when
/// libpng refuses the image (e.g. a zero width or height) or cwbvh was built without it.
std::vector<uint8_t> encode_png_rgb(const uint8_t* rgb, uint32_t width, uint32_t height);

/// Writes encode_png_rgb(...) to `path`; false with `error` (naming `path`) when the image
/// cannot be encoded or written.
[[nodiscard]] bool write_png_rgb(const std::string& path, const uint8_t* rgb, uint32_t width, uint32_t height,
                                 std::string& error);

}  // namespace cwbvh::tool
