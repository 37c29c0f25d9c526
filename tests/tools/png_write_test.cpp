// tools/cwbvh/png_write (libpng): the decoded pixels are exactly the input, the bytes
// are the same on every call (fixed compression settings), and failures are
// returned errors naming the file.
#include <gtest/gtest.h>
#include <png.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "png_write.h"

namespace cwbvh::tool {
namespace {

/// A test image with gradients, noise and flat runs (every filter type wins somewhere).
std::vector<uint8_t> pattern(uint32_t w, uint32_t h) {
    std::vector<uint8_t> rgb(size_t(w) * h * 3);
    uint32_t s = 12345;
    for (uint32_t y = 0; y < h; ++y) {
        for (uint32_t x = 0; x < w; ++x) {
            uint8_t* p = &rgb[(size_t(y) * w + x) * 3];
            s = s * 1664525u + 1013904223u;
            p[0] = uint8_t(x * 7 + y);
            p[1] = y < h / 2 ? uint8_t(s >> 24) : uint8_t(200);
            p[2] = uint8_t((x ^ y) * 3);
        }
    }
    return rgb;
}

/// Decodes an 8-bit RGB PNG with libpng's simplified API; empty on failure.
std::vector<uint8_t> decode(const std::vector<uint8_t>& png, uint32_t& w, uint32_t& h) {
    png_image image{};
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_memory(&image, png.data(), png.size())) return {};
    image.format = PNG_FORMAT_RGB;
    std::vector<uint8_t> rgb(PNG_IMAGE_SIZE(image));
    if (!png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr)) return {};
    w = image.width;
    h = image.height;
    return rgb;
}

TEST(PngWrite, DecodesToTheInputPixels) {
    for (const auto& [w, h] : {std::pair<uint32_t, uint32_t>{1, 1}, {37, 23}, {256, 300}}) {
        const std::vector<uint8_t> rgb = pattern(w, h);
        const std::vector<uint8_t> png = encode_png_rgb(rgb.data(), w, h);
        ASSERT_FALSE(png.empty());
        const uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
        ASSERT_TRUE(std::equal(signature, signature + 8, png.begin()));
        uint32_t dw = 0, dh = 0;
        EXPECT_EQ(decode(png, dw, dh), rgb) << w << "x" << h;
        EXPECT_EQ(dw, w);
        EXPECT_EQ(dh, h);
    }
}

TEST(PngWrite, SameBytesEveryCall) {
    const std::vector<uint8_t> rgb = pattern(200, 150);
    const std::vector<uint8_t> a = encode_png_rgb(rgb.data(), 200, 150);
    const std::vector<uint8_t> b = encode_png_rgb(rgb.data(), 200, 150);
    EXPECT_EQ(a, b);
    // Compressed: smaller than the raw scanlines (the old writer stored them).
    EXPECT_LT(a.size(), rgb.size());
}

TEST(PngWrite, WritesTheEncodedBytes) {
    const std::string path = std::string(CWBVH_BINARY_DIR) + "/png_write_test.png";
    const std::vector<uint8_t> rgb = pattern(64, 48);
    std::string err;
    ASSERT_TRUE(write_png_rgb(path, rgb.data(), 64, 48, err)) << err;
    std::ifstream in(path, std::ios::binary);
    const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_EQ(bytes, encode_png_rgb(rgb.data(), 64, 48));
    std::filesystem::remove(path);
}

TEST(PngWrite, ErrorsAreReturned) {
    std::string err;
    const uint8_t px[3] = {1, 2, 3};
    const std::string bad = std::string(CWBVH_BINARY_DIR) + "/no/such/dir/x.png";
    EXPECT_FALSE(write_png_rgb(bad, px, 1, 1, err));
    EXPECT_NE(err.find(bad), std::string::npos) << err;
    // A zero-sized image is not a PNG: libpng refuses it, reported, no crash.
    EXPECT_TRUE(encode_png_rgb(px, 0, 0).empty());
    err.clear();
    const std::string zero = std::string(CWBVH_BINARY_DIR) + "/png_write_zero.png";
    EXPECT_FALSE(write_png_rgb(zero, px, 0, 0, err));
    EXPECT_NE(err.find(zero), std::string::npos) << err;
    std::filesystem::remove(zero);
}

}  // namespace
}  // namespace cwbvh::tool
