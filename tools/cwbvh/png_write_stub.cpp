// PNG writer when cwbvh is built without libpng (the GPU-only configuration): every
// call fails, so `cwbvh render` reports why instead of writing an image.
#include "png_write.h"

namespace cwbvh::tool {

std::vector<uint8_t> encode_png_rgb(const uint8_t*, uint32_t, uint32_t) { return {}; }

bool write_png_rgb(const std::string& path, const uint8_t*, uint32_t, uint32_t, std::string& error) {
    error = path + ": cannot write PNG: cwbvh was built without libpng (install libpng-dev and reconfigure)";
    return false;
}

}  // namespace cwbvh::tool
