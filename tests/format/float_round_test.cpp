// cwbvh/format/float_round.h: the float neighbours against libm, and the directed
// double-to-float conversions against their definition (the largest float <= x, the
// smallest float >= x), which a float-to-double comparison checks exactly. The device's
// conversions are compared with these bit for bit by cwbvh_gpu_check's self-check
// (kernels/src/fast_node_selfcheck.cu).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "cwbvh/format/float_round.h"

namespace cwbvh {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kFltMax = std::numeric_limits<float>::max();

bool same(float x, float y) { return (std::isnan(x) && std::isnan(y)) || std::memcmp(&x, &y, sizeof x) == 0; }

TEST(FloatRound, NextFloatMatchesNextafter) {
    // Special values (+-0, subnormals, FLT_MAX, +-inf, NaN) and random bit patterns.
    std::vector<float> v = {0.0f, -0.0f, 1.0f, -1.0f, kInf, -kInf, std::numeric_limits<float>::quiet_NaN(),
                            std::numeric_limits<float>::denorm_min(), -std::numeric_limits<float>::denorm_min(),
                            std::numeric_limits<float>::min(), -std::numeric_limits<float>::min(), kFltMax, -kFltMax};
    std::mt19937 rng(7);
    for (int i = 0; i < 200000; ++i) {
        const uint32_t bits = rng();
        float f;
        std::memcpy(&f, &bits, sizeof f);
        v.push_back(f);
    }
    for (const float f : v) {
        ASSERT_TRUE(same(next_float_up(f), std::nextafter(f, kInf))) << f;
        ASSERT_TRUE(same(next_float_down(f), std::nextafter(f, -kInf))) << f;
    }
}

// Doubles where rounding is delicate: exact floats, midpoints between neighbours (where
// round-to-nearest goes either way), one double step off them, the ends of the float
// range and of the subnormals, values below the least subnormal, beyond FLT_MAX, +-inf.
std::vector<double> hard_doubles() {
    std::vector<double> v = {0.0, -0.0, HUGE_VAL, -HUGE_VAL, 0x1p-150, 0x1p-149, 0x1.8p-149, 0x1p-1074,
                             0x1p-200, double(kFltMax), 0x1.ffffffp127, 0x1.fffffe8p127, 0x1p128, 0x1p200, 1e300};
    std::mt19937_64 rng(11);
    for (int i = 0; i < 100000; ++i) {
        float f;
        const uint32_t bits = uint32_t(rng()) & 0x7F7FFFFFu;  // finite
        std::memcpy(&f, &bits, sizeof f);
        const double a = f, b = std::nextafter(f, kInf);  // neighbours (b may be +inf past FLT_MAX)
        const double mid = std::isinf(b) ? 0x1.ffffffp127 : a + (b - a) / 2;  // exact in double
        for (const double x : {a, mid, std::nextafter(mid, 0.0), std::nextafter(mid, HUGE_VAL)}) {
            v.push_back(x);
            v.push_back(-x);
        }
    }
    for (int i = 0; i < 100000; ++i) {  // random doubles, 2^-170 .. 2^170
        const uint64_t e = 1023u - 170u + rng() % 341u;
        const uint64_t u = (rng() & 0x800FFFFFFFFFFFFFull) | (e << 52);
        double x;
        std::memcpy(&x, &u, sizeof x);
        v.push_back(x);
    }
    return v;
}

TEST(FloatRound, DownIsTheLargestFloatAtOrBelowAndUpTheSmallestAtOrAbove) {
    size_t inexact = 0;
    for (const double x : hard_doubles()) {
        if (std::isinf(x)) continue;  // no float beyond: SignOfZeroAndTheEnds
        const float d = float_round_down(x), u = float_round_up(x);
        ASSERT_FALSE(std::isnan(d) || std::isnan(u)) << x;
        // d <= x < next above d; u >= x > next below u (+-inf are floats: the largest
        // float <= 1e300 is FLT_MAX, the largest <= -1e300 is -inf).
        ASSERT_LE(double(d), x) << std::hexfloat << x;
        ASSERT_GT(double(next_float_up(d)), x) << std::hexfloat << x;
        ASSERT_GE(double(u), x) << std::hexfloat << x;
        ASSERT_LT(double(next_float_down(u)), x) << std::hexfloat << x;
        if (double(d) == x) {
            ASSERT_TRUE(same(d, u)) << std::hexfloat << x;  // exact: both the value itself
        } else {
            ASSERT_TRUE(same(next_float_up(d), u)) << std::hexfloat << x;  // neighbours
            ++inexact;
        }
    }
    EXPECT_GT(inexact, 500000u);  // most inputs round: the checks above did test directions
}

TEST(FloatRound, SignOfZeroAndTheEnds) {
    // A result of zero keeps x's sign (-0.0 rounds to -0, a tiny negative value up to -0
    // and down to the least negative subnormal); beyond FLT_MAX the bound that cannot be
    // finite is infinite and the other is +-FLT_MAX.
    EXPECT_TRUE(same(float_round_down(-0.0), -0.0f));
    EXPECT_TRUE(same(float_round_up(0.0), 0.0f));
    EXPECT_TRUE(same(float_round_up(0x1p-200), std::numeric_limits<float>::denorm_min()));
    EXPECT_TRUE(same(float_round_down(0x1p-200), 0.0f));
    EXPECT_TRUE(same(float_round_down(-0x1p-200), -std::numeric_limits<float>::denorm_min()));
    EXPECT_TRUE(same(float_round_up(-0x1p-200), -0.0f));
    EXPECT_TRUE(same(float_round_down(0x1p128), kFltMax));
    EXPECT_TRUE(same(float_round_up(0x1p128), kInf));
    EXPECT_TRUE(same(float_round_down(-0x1p128), -kInf));
    EXPECT_TRUE(same(float_round_up(-0x1p128), -kFltMax));
    for (const double inf : {HUGE_VAL, -HUGE_VAL}) {  // an infinity is a float: itself both ways
        EXPECT_TRUE(same(float_round_down(inf), float(inf)));
        EXPECT_TRUE(same(float_round_up(inf), float(inf)));
    }
}

TEST(FloatRound, NanGivesTheBoundThatExcludesNothing) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_TRUE(same(float_round_down(nan), -kInf));
    EXPECT_TRUE(same(float_round_up(nan), kInf));
}

}  // namespace
}  // namespace cwbvh
