// fp16.h's host emulation against independent exact references: the binary16 fma,
// conversions and compares the fast node test uses (node_intersect_fast.h) must give the
// bits the GPU gives, or the warp model, the kernel emulation and the node test's contract
// test would check something other than what the kernel runs.
//
// References: every finite half value, sorted, as an exact integer multiple of 2^-48
// (__int128); an exact a * b + c of halves is such a multiple too, and its rounding is a
// lookup between two neighbours. For the float fmas with directed rounding: f128
// (113-bit significand) holds a * b + c exactly for the operand ranges drawn here.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "cwbvh/kernels/fp16.h"

namespace cwbvh {
namespace {

__extension__ typedef __int128 i128;        // -Wpedantic: GCC/Clang extensions, x86-64 here
__extension__ typedef __float128 f128;

// Exact value of a finite half, times 2^48.
i128 half_scaled(uint16_t h) {
    const uint32_t e = (h >> 10) & 0x1Fu, m = h & 0x3FFu;
    const i128 mag = e == 0 ? i128(m) << 24 : i128(m | 0x400u) << (e + 23);  // m 2^-24, (1024+m) 2^(e-25)
    return (h & 0x8000u) ? -mag : mag;
}

struct HalfTable {
    std::vector<std::pair<i128, uint16_t>> v;  // finite halves by value (+0 stands for both zeros)
    HalfTable() {
        for (uint32_t h = 0; h < 0x10000u; ++h) {
            if (((h >> 10) & 0x1Fu) == 31 || h == 0x8000u) continue;
            v.push_back({half_scaled(uint16_t(h)), uint16_t(h)});
        }
        std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    }
};
const HalfTable& table() {
    static const HalfTable t;
    return t;
}

// x (times 2^48) rounded to a half: mode 0 nearest even, -1 down, +1 up; neg_zero: the
// sign of a zero result (IEEE: the sign of x, or of the operands for an exact zero).
uint16_t round_scaled(i128 x, int mode, bool neg_zero) {
    const auto& v = table().v;
    const i128 max = half_scaled(0x7BFFu);
    const i128 inf_edge = max + (i128(1) << (15 - 10 + 48 - 1));  // 65520: halfway to 2^16
    if (x > max) {
        if (mode < 0 || (mode == 0 && x < inf_edge)) return 0x7BFFu;
        return 0x7C00u;
    }
    if (x < -max) {
        if (mode > 0 || (mode == 0 && x > -inf_edge)) return 0xFBFFu;
        return 0xFC00u;
    }
    auto it = std::lower_bound(v.begin(), v.end(), x, [](const auto& a, i128 b) { return a.first < b; });
    uint16_t r;
    if (it->first == x) {
        r = it->second;
    } else {
        const auto hi = *it, lo = *(it - 1);
        if (mode < 0) r = lo.second;
        else if (mode > 0) r = hi.second;
        else {
            const i128 dl = x - lo.first, dh = hi.first - x;
            if (dl != dh) r = dl < dh ? lo.second : hi.second;
            else r = (lo.second & 1u) == 0 ? lo.second : hi.second;  // tie: even significand
        }
    }
    if ((r & 0x7FFFu) == 0) r = neg_zero ? 0x8000u : 0u;
    return r;
}

uint16_t random_half(std::mt19937_64& g) {
    for (;;) {
        uint16_t h = uint16_t(g());
        switch (g() % 4) {
            case 0: h = uint16_t((h & 0x83FFu) | ((4 + g() % 12) << 10)); break;  // |x| in [2^-11, 2^1)
            case 1: h &= 0x83FFu; break;                                           // subnormal
            default: break;
        }
        if (((h >> 10) & 0x1Fu) != 31) return h;
    }
}

TEST(Fp16, HalfFmaIsTheCorrectlyRoundedFma) {
    std::mt19937_64 g(2027);
    uint64_t n = 0;
    for (int i = 0; i < 400000; ++i) {
        uint16_t a = random_half(g), b = random_half(g), c = random_half(g);
        if (i % 4 == 0) {
            // c near -a*b: cancellation, ties and exact zeros.
            const double p = fp16_host::half_to_double(a) * fp16_host::half_to_double(b);
            c = fp16_host::half_from_double(-p, int(g() % 3) - 1);
            if (((c >> 10) & 0x1Fu) == 31) continue;
        }
        // Exact: a and b are multiples of 2^-24, so (a 2^24)(b 2^24) = a b 2^48 is an integer.
        const i128 x = (half_scaled(a) >> 24) * (half_scaled(b) >> 24) + half_scaled(c);
        const bool prod_neg = ((a ^ b) & 0x8000u) != 0;
        const bool neg_zero = x < 0 || (x == 0 && prod_neg && (c & 0x8000u) && half_scaled(c) == 0 &&
                                        (half_scaled(a) == 0 || half_scaled(b) == 0));
        const uint16_t want = round_scaled(x, 0, neg_zero);
        const uint32_t got = h2_fma(fp16_host::pair(a, c), fp16_host::pair(b, b), fp16_host::pair(c, a));
        ASSERT_EQ(fp16_host::lane(got, 0), want) << std::hex << a << " " << b << " " << c;
        ++n;
    }
    EXPECT_GT(n, 390000u);
}

TEST(Fp16, FloatToHalfRoundsToNearestDownAndUp) {
    std::mt19937_64 g(99);
    for (int i = 0; i < 400000; ++i) {
        float x;
        if (i < 70000) x = std::ldexp(float(int32_t(g() % 4096) - 2048) / 1024.0f, int(g() % 46) - 30);  // near the grid
        else {
            const uint32_t bits = uint32_t(g());
            x = bits_to_float((bits & 0x807FFFFFu) | ((102 + uint32_t(g() % 48)) << 23));  // 2^-25 .. 2^22
        }
        const double xd = x;
        const i128 xs = i128(std::ldexp(xd, 48));  // exact: x is a multiple of 2^-48
        ASSERT_EQ(double(xs), std::ldexp(xd, 48));
        const bool neg = std::signbit(x);
        const uint16_t rn = round_scaled(xs, 0, neg), rd = round_scaled(xs, -1, neg), ru = round_scaled(xs, 1, neg);
        ASSERT_EQ(fp16_host::lane(h2_pack(x, 0.0f), 0), rn) << x;
        ASSERT_EQ(fp16_host::lane(h2_broadcast_rd(x), 0), rd) << x;
        ASSERT_EQ(fp16_host::lane(h2_broadcast_ru(x), 1), ru) << x;
    }
    // Beyond the half range: RN and the outward direction give infinities, the inward
    // direction 65504; infinities stay infinite.
    EXPECT_EQ(fp16_host::lane(h2_pack(65519.0f, 0.0f), 0), 0x7BFFu);
    EXPECT_EQ(fp16_host::lane(h2_pack(65520.0f, 0.0f), 0), 0x7C00u);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_rd(1e30f), 0), 0x7BFFu);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_ru(1e30f), 0), 0x7C00u);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_rd(-1e30f), 0), 0xFC00u);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_ru(-1e30f), 0), 0xFBFFu);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_ru(kInfinity), 0), 0x7C00u);
    // Below the smallest subnormal (2^-24): RN to zero (2^-25 is a tie, to even 0), up to 2^-24.
    EXPECT_EQ(fp16_host::lane(h2_pack(std::ldexp(1.0f, -25), 0.0f), 0), 0x0000u);
    EXPECT_EQ(fp16_host::lane(h2_pack(std::ldexp(1.5f, -25), 0.0f), 0), 0x0001u);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_ru(1e-30f), 0), 0x0001u);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_rd(-1e-30f), 0), 0x8001u);
    EXPECT_EQ(fp16_host::lane(h2_broadcast_rd(1e-30f), 0), 0x0000u);
}

float random_float(std::mt19937_64& g, int emin, int emax) {
    const uint32_t bits = uint32_t(g());
    return bits_to_float((bits & 0x807FFFFFu) | (uint32_t(127 + emin + int(g() % uint64_t(emax - emin + 1))) << 23));
}

// Round the exact f128 v to float in a direction.
float directed(f128 v, int mode) {
    float f = float(v);  // round to nearest
    if (mode < 0 && f128(f) > v) f = std::nextafter(f, -kInfinity);
    if (mode > 0 && f128(f) < v) f = std::nextafter(f, kInfinity);
    return f;
}

// RD (mode -1) or RU (+1) of the exact a*b + c, with the sign IEEE 754 (6.3) gives an exact
// zero, as the device's FFMA.RM/RP and FADD.RM/RP do: -0 under RD unless the product and c
// are both +0; +0 under RU unless both are -0.
float directed_fma(float a, float b, float c, int mode) {
    // Exact: the bits of a*b + c span at most 2^21 .. 2^-66 here, under 113.
    const f128 exact = f128(a) * f128(b) + f128(c);
    if (exact != 0) return directed(exact, mode);
    const bool p_neg = std::signbit(a) != std::signbit(b), c_neg = std::signbit(c);
    return mode < 0 ? (!p_neg && !c_neg ? 0.0f : -0.0f) : (p_neg && c_neg ? -0.0f : 0.0f);
}

// Bit for bit, so that the sign of a zero counts (the GPU self-check compares bits).
TEST(Fp16, FloatFmaAndSumsRoundDownAndUp) {
    std::mt19937_64 g(5);
    for (int i = 0; i < 300000; ++i) {
        float a = random_float(g, -10, 10), b = random_float(g, -10, 10);
        float c = random_float(g, -20, 20);
        if (i % 3 == 0) c = -float(double(a) * double(b));  // cancellation
        if (i % 5 == 1) {  // exact zeros: short significands make a*b a float; a - a
            a = bits_to_float(float_to_bits(a) & 0xFFFF0000u);
            b = bits_to_float(float_to_bits(b) & 0xFFFF0000u);
            c = i % 2 ? -a * b : a;
        }
        if (i % 7 == 2) c = (i % 2) ? -0.0f : 0.0f;  // signed zero terms
        if (i % 11 == 3) a = (i % 2) ? -0.0f : 0.0f;
        ASSERT_EQ(float_to_bits(fma_rd(a, b, c)), float_to_bits(directed_fma(a, b, c, -1))) << a << " " << b << " " << c;
        ASSERT_EQ(float_to_bits(fma_ru(a, b, c)), float_to_bits(directed_fma(a, b, c, +1))) << a << " " << b << " " << c;
        ASSERT_EQ(float_to_bits(sub_rd(a, c)), float_to_bits(directed_fma(a, 1.0f, -c, -1))) << a << " " << c;
        ASSERT_EQ(float_to_bits(add_ru(a, c)), float_to_bits(directed_fma(a, 1.0f, c, +1))) << a << " " << c;
    }
    // Exact zeros by hand (IEEE 754 6.3).
    const uint32_t kMinusZero = 0x80000000u;
    EXPECT_EQ(float_to_bits(fma_rd(1.0f, 1.0f, -1.0f)), kMinusZero);
    EXPECT_EQ(float_to_bits(sub_rd(0.5f, 0.5f)), kMinusZero);
    EXPECT_EQ(float_to_bits(sub_rd(0.0f, 0.0f)), kMinusZero);  // +0 - +0 = +0 + -0
    EXPECT_EQ(float_to_bits(sub_rd(0.0f, -0.0f)), 0u);         // +0 + +0
    EXPECT_EQ(float_to_bits(fma_rd(0.0f, 1.0f, -0.0f)), kMinusZero);
    EXPECT_EQ(float_to_bits(fma_rd(0.0f, 1.0f, 0.0f)), 0u);
    EXPECT_EQ(float_to_bits(fma_ru(1.0f, 1.0f, -1.0f)), 0u);
    EXPECT_EQ(float_to_bits(fma_ru(-0.0f, 1.0f, -0.0f)), kMinusZero);
    EXPECT_EQ(float_to_bits(add_ru(0.0f, -0.0f)), 0u);
    // x = 1025 - 2^-46 needs 57 bits: a plain double sum rounds it to 1025, a float
    // boundary, and RD would keep 1025 (double rounding); round-to-odd keeps the sticky bit.
    const float a = 1.0f + std::ldexp(1.0f, -23), b = 1.0f - std::ldexp(1.0f, -23);
    EXPECT_EQ(fma_rd(a, b, 1024.0f), std::nextafter(1025.0f, 0.0f));
    EXPECT_EQ(fma_ru(a, -b, -1024.0f), std::nextafter(-1025.0f, 0.0f));
    EXPECT_EQ(fma_ru(a, b, 1024.0f), 1025.0f);
    EXPECT_EQ(fma_ru(kInfinity, 2.0f, -1.0f), kInfinity);
    EXPECT_EQ(fma_rd(3e38f, 2.0f, 0.0f), 3.4028234663852886e+38f);  // overflow rounds down to FLT_MAX
    EXPECT_EQ(fma_ru(3e38f, 2.0f, 0.0f), kInfinity);
}

TEST(Fp16, PairedMinCompareAndIntegerMaxMin) {
    // Lane-wise, low half first, as the device orders a half2.
    const uint32_t a = fp16_host::pair(0x3C00u /*1*/, 0xC000u /*-2*/), b = fp16_host::pair(0x4000u /*2*/, 0x8000u /*-0*/);
    EXPECT_EQ(h2_min(a, b), fp16_host::pair(0x3C00u, 0xC000u));
    // PTX min counts -0 below +0, whichever operand it is.
    EXPECT_EQ(h2_min(fp16_host::pair(0x0000u, 0x8000u), fp16_host::pair(0x8000u, 0x0000u)), fp16_host::pair(0x8000u, 0x8000u));
    bool lo = false, hi = false;
    h2_le(a, b, lo, hi);
    EXPECT_TRUE(lo);
    EXPECT_TRUE(hi);
    h2_le(fp16_host::pair(0x0000u, 0x3C01u), fp16_host::pair(0x8000u, 0x3C00u), lo, hi);
    EXPECT_TRUE(lo);   // +0 <= -0
    EXPECT_FALSE(hi);  // 1 + 2^-10 > 1
    EXPECT_EQ(h2_lo(0x12345678u), 0x56785678u);
    EXPECT_EQ(h2_hi(0x12345678u), 0x12341234u);
    // Signed 16-bit lanes: a negative half is a negative integer, and the relu keeps 0.
    EXPECT_EQ(vimax3_s16x2_relu(fp16_host::pair(0x8001u, 0x3C00u), fp16_host::pair(0xFC00u, 0x4000u),
                                fp16_host::pair(0xBC00u, 0x0001u)),
              fp16_host::pair(0x0000u, 0x4000u));
    EXPECT_EQ(vimin3_s16x2(fp16_host::pair(0x3C00u, 0x7C00u), fp16_host::pair(0x4000u, 0x3C00u),
                           fp16_host::pair(0xBC00u, 0x7BFFu)),
              fp16_host::pair(0xBC00u, 0x3C00u));
    EXPECT_EQ(umax3(3u, 0xFFFFFFF0u, 7u), 0xFFFFFFF0u);
}

}  // namespace
}  // namespace cwbvh
