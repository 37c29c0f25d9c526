// Quantization tests (Ylitie et al. 2017, 3.3, made conservative under the
// normative decode_plane): property test, exponent edge cases (the
// ceil(log2f()) off-by-one), zero extents, tiny/huge/far-from-origin boxes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>

#include "../result_util.h"
#include "cwbvh/compiler/quantize.h"
#include "cwbvh/format/node_decode.h"

namespace cwbvh::compiler {
namespace {

bool long_tests() {
    const char* v = std::getenv("CWBVH_LONG_TESTS");
    return v && std::strcmp(v, "1") == 0;
}

// Checks one quantized node: containment, range, q_lo <= q_hi, minimal exponent.
void check_node(const Aabb (&boxes)[8], uint8_t used, const CwbvhNode& node, uint64_t& failures) {
    Aabb frame;
    for (int s = 0; s < 8; ++s)
        if (used >> s & 1) frame.grow(boxes[s]);
    for (int a = 0; a < 3; ++a) {
        bool ok = node.p[a] == frame.lo[a] && node.e[a] >= 1 && node.e[a] <= 254;
        ok = ok && decode_plane(node.p[a], node.e[a], 255) >= frame.hi[a];
        if (node.e[a] > 1) ok = ok && decode_plane(node.p[a], uint8_t(node.e[a] - 1), 255) < frame.hi[a];
        for (int s = 0; s < 8 && ok; ++s) {
            if (!(used >> s & 1)) continue;
            ok = node.q_lo[a][s] <= node.q_hi[a][s] &&
                 decode_plane(node.p[a], node.e[a], node.q_lo[a][s]) <= boxes[s].lo[a] &&
                 decode_plane(node.p[a], node.e[a], node.q_hi[a][s]) >= boxes[s].hi[a];
        }
        if (!ok && failures++ < 10) {
            ADD_FAILURE() << "axis " << a << " p " << node.p[a] << " e " << int(node.e[a]) << " frame ["
                          << frame.lo[a] << ", " << frame.hi[a] << "]";
        }
    }
}

float ulps(float x, int n) {
    for (; n > 0; --n) x = std::nextafter(x, HUGE_VALF);
    for (; n < 0; ++n) x = std::nextafter(x, -HUGE_VALF);
    return x;
}

TEST(Quantize, PropertyRandomBoxes) {
    // ~0.3 s per 10^6 boxes (-O2, one thread); CWBVH_LONG_TESTS=1 runs 3 * 10^7.
    const uint64_t target = long_tests() ? 30'000'000ull : 1'000'000ull;  // child boxes
    std::mt19937_64 rng(12345);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    uint64_t boxes_done = 0, failures = 0, zero_axes = 0;
    while (boxes_done < target) {
        // Per node: a scale 2^k across the float range, an origin (0, near,
        // far relative to the scale, or huge), extents possibly at 255*2^j +- ulps.
        const int k = int(rng() % 250) - 140;  // 2^-140 .. 2^109
        const double scale = std::ldexp(1.0, k);
        double origin[3];
        for (int a = 0; a < 3; ++a) {
            switch (rng() % 4) {
                case 0: origin[a] = 0.0; break;
                case 1: origin[a] = (u01(rng) - 0.5) * scale * 4; break;
                case 2: origin[a] = (u01(rng) - 0.5) * scale * std::ldexp(1.0, int(rng() % 40)); break;
                default: origin[a] = (u01(rng) - 0.5) * std::ldexp(1.0, int(rng() % 126)); break;
            }
        }
        const int mode = int(rng() % 8);
        Aabb boxes[8];
        uint8_t used = 0;
        const int count = 1 + int(rng() % 8);
        for (int c = 0; c < count; ++c) {
            const int s = int(rng() % 8);
            used = uint8_t(used | (1u << s));
            for (int a = 0; a < 3; ++a) {
                float lo, hi;
                if (mode == 0 && a == 1) {  // zero-extent axis for the whole node
                    lo = hi = float(origin[a]);
                } else {
                    double x0 = origin[a] + u01(rng) * scale, x1 = origin[a] + u01(rng) * scale;
                    if (x0 > x1) std::swap(x0, x1);
                    if (mode == 1) x1 = x0;  // flat child
                    lo = float(x0);
                    hi = float(x1);
                    if (mode == 2 && c == 0) {  // extent at 255 * 2^j +- a few ulps
                        lo = float(origin[a]);
                        hi = ulps(float(double(lo) + 255.0 * scale), int(rng() % 9) - 4);
                        if (hi < lo) hi = lo;
                    }
                }
                if (std::fabs(lo) > 0x1p125f || std::fabs(hi) > 0x1p125f) lo = hi = 0.0f;
                boxes[s].lo[a] = lo;
                boxes[s].hi[a] = hi;
            }
            ++boxes_done;
        }
        if (mode == 3) {  // children touching each other's / the frame's bounds
            for (int s = 0; s < 8; ++s)
                if (used >> s & 1) boxes[s] = boxes[__builtin_ctz(used)];
        }
        CwbvhNode node{};
        std::string error;
        ASSERT_TRUE(::cwbvh::test::ok(quantize_node(boxes, used, node), error)) << error;
        check_node(boxes, used, node, failures);
        for (int a = 0; a < 3; ++a) zero_axes += node.e[a] == 1;
    }
    EXPECT_EQ(failures, 0u);
    EXPECT_GT(zero_axes, 0u);
}

// Naive exponent of the public implementations: ceil(log2f(ext / 255)).
int naive_exponent(float ext) { return int(std::ceil(std::log2f(ext / 255.0f))) + 127; }

TEST(Quantize, ExtentJustAbove255TimesPowerOfTwo) {
    int naive_bad = 0;
    for (int k = -120; k <= 100; ++k) {
        for (int d = -4; d <= 64; ++d) {
            const float p = 0.0f;
            const float hi = ulps(std::ldexp(255.0f, k), d);
            uint8_t e = 0;
            ASSERT_TRUE(choose_exponent(p, hi, e));
            EXPECT_GE(decode_plane(p, e, 255), hi);
            if (e > 1) {
                EXPECT_LT(decode_plane(p, uint8_t(e - 1), 255), hi);
            }
            // Exactly 255*2^k (d = 0) needs exponent k, just above needs k + 1.
            EXPECT_EQ(int(e) - 127, d <= 0 ? k : k + 1) << k << " " << d;
            uint8_t qlo, qhi;
            quantize_interval(p, e, p, hi, qlo, qhi);
            EXPECT_EQ(qlo, 0);
            EXPECT_GE(decode_plane(p, e, qhi), hi);
            const int ne = naive_exponent(hi);
            if (ne >= 1 && ne <= 254 && std::ceil(double(hi) / std::ldexp(1.0, ne - 127)) > 255) ++naive_bad;
        }
    }
    // The bug exists for the naive formula (q_hi would be 256 -> wraps to 0).
    EXPECT_GT(naive_bad, 0);
}

TEST(Quantize, ZeroExtentAxis) {
    Aabb boxes[8];
    for (int s = 0; s < 3; ++s) {
        boxes[s].lo = {float(s), 5.0f, -1e7f};
        boxes[s].hi = {float(s) + 1, 5.0f, -1e7f};
    }
    CwbvhNode node{};
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(quantize_node(boxes, 0x07, node), error)) << error;
    EXPECT_EQ(node.e[1], 1);
    EXPECT_EQ(node.e[2], 1);
    for (int s = 0; s < 8; ++s) {
        EXPECT_EQ(node.q_lo[1][s], 0);
        EXPECT_EQ(node.q_hi[1][s], 0);
        EXPECT_EQ(node.q_hi[2][s], 0);
    }
    const Aabb d = decode_child_box(node, 1);
    EXPECT_EQ(d.lo[1], 5.0f);
    EXPECT_EQ(d.hi[1], 5.0f);
}

TEST(Quantize, TinyBoxesClampToSmallestExponent) {
    Aabb boxes[8];
    boxes[0].lo = {1e-44f, 0.0f, -1e-40f};  // subnormals
    boxes[0].hi = {3e-44f, 1e-42f, 1e-40f};
    boxes[5].lo = {0.0f, 0.0f, 0.0f};
    boxes[5].hi = {1e-44f, 1e-45f, 0.0f};
    CwbvhNode node{};
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(quantize_node(boxes, 0x21, node), error)) << error;
    uint64_t failures = 0;
    check_node(boxes, 0x21, node, failures);
    EXPECT_EQ(failures, 0u);
    for (int a = 0; a < 3; ++a) EXPECT_EQ(node.e[a], 1);
}

TEST(Quantize, FarFromOriginSmallDetail) {
    std::mt19937 rng(4);
    std::uniform_real_distribution<float> d(0.0f, 1e-2f);
    uint64_t failures = 0;
    for (int it = 0; it < 10000; ++it) {
        Aabb boxes[8];
        for (int s = 0; s < 8; ++s) {
            for (int a = 0; a < 3; ++a) {
                const float base = a == 0 ? 1e7f : a == 1 ? -1e7f : 12345.678f;
                boxes[s].lo[a] = base + d(rng);
                boxes[s].hi[a] = boxes[s].lo[a] + d(rng);
            }
        }
        CwbvhNode node{};
        std::string error;
        ASSERT_TRUE(::cwbvh::test::ok(quantize_node(boxes, 0xFF, node), error)) << error;
        check_node(boxes, 0xFF, node, failures);
    }
    EXPECT_EQ(failures, 0u);
}

TEST(Quantize, HugeExtentsEncodeUpTo2Pow125AndRejectOverflow) {
    Aabb boxes[8];
    boxes[0].lo = {-0x1p125f, -0x1p125f, 0.0f};
    boxes[0].hi = {0x1p125f, 0.0f, 0x1p125f};
    CwbvhNode node{};
    std::string error;
    ASSERT_TRUE(::cwbvh::test::ok(quantize_node(boxes, 0x01, node), error)) << error;
    uint64_t failures = 0;
    check_node(boxes, 0x01, node, failures);
    EXPECT_EQ(failures, 0u);
    boxes[0].lo = {-3e38f, 0.0f, 0.0f};
    boxes[0].hi = {3e38f, 1.0f, 1.0f};
    EXPECT_FALSE(::cwbvh::test::ok(quantize_node(boxes, 0x01, node), error));
    EXPECT_NE(error.find("cannot be encoded"), std::string::npos);
    boxes[0].hi[0] = std::nanf("");
    EXPECT_FALSE(::cwbvh::test::ok(quantize_node(boxes, 0x01, node), error));
    EXPECT_FALSE(::cwbvh::test::ok(quantize_node(boxes, 0x00, node), error));
}

TEST(Quantize, RoundingDirection) {
    // A child strictly inside one grid cell: q_lo rounds down, q_hi up.
    const float p = 1.0f;
    uint8_t e = 0;
    ASSERT_TRUE(choose_exponent(p, 1.0f + 255.0f, e));
    EXPECT_EQ(e, 127);  // scale 1
    uint8_t qlo, qhi;
    quantize_interval(p, e, 10.5f, 11.25f, qlo, qhi);
    EXPECT_EQ(qlo, 9);
    EXPECT_EQ(qhi, 11);
    quantize_interval(p, e, 11.0f, 11.0f, qlo, qhi);  // on a grid plane: exact
    EXPECT_EQ(qlo, 10);
    EXPECT_EQ(qhi, 10);
}

}  // namespace
}  // namespace cwbvh::compiler
