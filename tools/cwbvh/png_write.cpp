// PNG writer on libpng (see png_write.h).
#include "png_write.h"

#include "cwbvh/format/file_io.h"

#include <png.h>
#include <zlib.h>

#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>

namespace cwbvh::tool {
namespace {

struct Sink {
    std::vector<uint8_t>* out;
    char message[256];  ///< libpng's error text (plain array: survives the longjmp)
};

void on_write(png_structp png, png_bytep data, png_size_t size) {
    auto* sink = static_cast<Sink*>(png_get_io_ptr(png));
    sink->out->insert(sink->out->end(), data, data + size);
}
void on_flush(png_structp) {}

void on_error(png_structp png, png_const_charp message) {
    auto* sink = static_cast<Sink*>(png_get_error_ptr(png));
    std::snprintf(sink->message, sizeof(sink->message), "%s", message);
    png_longjmp(png, 1);
}
void on_warning(png_structp, png_const_charp) {}

/// Encodes into *sink->out; false with sink->message on a libpng error. Only plain
/// locals live in this frame, so libpng's longjmp back to setjmp skips no destructor.
bool encode(Sink* sink, const uint8_t* rgb, uint32_t width, uint32_t height) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, sink, on_error, on_warning);
    if (!png) {
        std::snprintf(sink->message, sizeof(sink->message), "out of memory");
        return false;
    }
    png_infop info = png_create_info_struct(png);
    if (!info) {
        png_destroy_write_struct(&png, nullptr);
        std::snprintf(sink->message, sizeof(sink->message), "out of memory");
        return false;
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return false;
    }
    png_set_write_fn(png, sink, on_write, on_flush);
    // Fixed settings (not libpng's defaults, which may change between versions), so the
    // same pixels give the same bytes with this libpng and zlib: zlib level 6, the
    // Z_FILTERED strategy, 32 KiB window, memory level 8; libpng's adaptive choice among
    // all five row filters (deterministic: minimum sum of absolute differences).
    png_set_compression_level(png, 6);
    png_set_compression_strategy(png, Z_FILTERED);
    png_set_compression_window_bits(png, 15);
    png_set_compression_mem_level(png, 8);
    png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_ALL_FILTERS);
    png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_BASE,
                 PNG_FILTER_TYPE_BASE);
    png_write_info(png, info);
    const size_t row = size_t(width) * 3;
    for (uint32_t y = 0; y < height; ++y) png_write_row(png, rgb + y * row);
    png_write_end(png, nullptr);
    png_destroy_write_struct(&png, &info);
    return true;
}

}  // namespace

std::vector<uint8_t> encode_png_rgb(const uint8_t* rgb, uint32_t width, uint32_t height) {
    std::vector<uint8_t> out;
    Sink sink{&out, {}};
    if (!encode(&sink, rgb, width, height)) out.clear();
    return out;
}

bool write_png_rgb(const std::string& path, const uint8_t* rgb, uint32_t width, uint32_t height, std::string& error) {
    std::vector<uint8_t> png;
    Sink sink{&png, {}};
    if (!encode(&sink, rgb, width, height)) {
        error = path + ": cannot encode the PNG: " + sink.message;
        return false;
    }
    const Result r = write_file_atomic(path, png.data(), png.size());  // whole or not at all
    if (!r.ok()) error = r.message;
    return r.ok();
}

}  // namespace cwbvh::tool
