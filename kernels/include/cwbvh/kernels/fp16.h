// Binary16 (half) arithmetic for the fast node test (node_intersect_fast.h), on packed
// pairs in 32-bit words, and the float fmas with directed rounding it needs. On the
// device each function is one instruction (or a few on older GPUs); on the host each is
// emulated with the device's exact semantics, so that the CPU warp model, the kernel
// emulation and tests/traverse/node_intersect_test.cpp run what the kernel runs, bit
// for bit. tests/traverse/fp16_test.cpp checks the emulation against an independent
// exact (integer) computation.
//
// Semantics (PTX ISA): fma.rn.f16x2 rounds once to nearest even, keeps subnormals
// (no .ftz; nvcc's -ftz flag applies to f32 only); cvt.rn.f16x2.f32 rounds to nearest
// even; cvt.rm and cvt.rp.f16.f32 round down and up (beyond +-65504 toward zero where
// that is the direction: RD of a huge positive value is 65504); min.f16x2 and
// setp.le.f16x2 compare as IEEE values (no operand here is ever NaN); the DPX s16x2
// functions work on the two halves as signed 16-bit integers. For finite half
// operands a * b + c is exact in double (at most 41 bits apart), so round-to-odd below
// matters only for the float fmas.
#pragma once

#include <cstdint>

#include "cwbvh/format/float_round.h"
#include "cwbvh/kernels/fp.h"

#if defined(__CUDA_ARCH__)
#include <cuda_fp16.h>
#else
#include <cmath>
#endif

namespace cwbvh {

#if !defined(__CUDA_ARCH__)
namespace fp16_host {

/// a * b + c rounded to double with round-to-odd: the exact value when it is a double,
/// otherwise the neighbour whose last significand bit is 1. Rounding that once more to
/// 24 or 11 bits, in any mode, gives the correctly rounded a * b + c (53 >= p + 2), which
/// rounding a plain double sum could miss (double rounding). For float or half operands
/// (the product is exact in double) and finite results.
inline double fma_round_to_odd(double a, double b, double c) {
    const double p = a * b;  // exact: at most 24 + 24 significant bits
    const double s = p + c;
    if (!std::isfinite(s)) return s;
    const double bv = s - p;  // TwoSum (Knuth): s + e == p + c exactly
    const double e = (p - (s - bv)) + (c - bv);
    if (e == 0.0) return s;
    uint64_t u;
    memcpy(&u, &s, sizeof u);
    if ((u & 1u) == 0) {
        // s is even: the round-to-odd result is its other neighbour of p + c, one ulp
        // toward e (sign-magnitude: +1 grows |s|). s != 0 here (e != 0).
        u = ((e > 0) == (s > 0)) ? u + 1 : u - 1;
        double r;
        memcpy(&r, &u, sizeof r);
        return r;
    }
    return s;
}

/// x (a double holding a float result, or round-to-odd of one) rounded to float:
/// mode -1 down, +1 up.
inline float float_directed(double x, int mode) {
    if (std::isnan(x)) return float(x);  // the instruction's NaN (float_round_* give +-inf)
    return mode < 0 ? float_round_down(x) : mode > 0 ? float_round_up(x) : float(x);
}

/// RD(a * b + c) to float, as FFMA.RM and FADD.RM round (a, b, c floats). An exact zero
/// takes the sign IEEE 754 (6.3) gives it under roundTowardNegative: -0, unless the product
/// and c are both +0. The double sum rounds to nearest, where that zero is +0: without this,
/// fma_rd(1, 1, -1) and sub_rd(x, x) were +0 on the host and -0 on the device. (Round-up
/// needs nothing: there an exact zero is +0 unless both terms are -0, as in the double sum.)
inline float fma_down(double a, double b, double c) {
    const double r = fma_round_to_odd(a, b, c);  // 0 only for an exact zero (float terms)
    if (r == 0.0) return !std::signbit(a * b) && !std::signbit(c) ? 0.0f : -0.0f;
    return float_directed(r, -1);
}

/// x rounded to binary16 bits: mode 0 to nearest even, -1 down, +1 up.
inline uint16_t half_from_double(double x, int mode) {
    if (std::isnan(x)) return 0x7E00u;
    const uint16_t sign = std::signbit(x) ? 0x8000u : 0u;
    if (std::isinf(x)) return uint16_t(sign | 0x7C00u);
    const double a = std::fabs(x);
    int e2 = 0;
    (void)std::frexp(a, &e2);
    int ex = e2 - 1;  // a in [2^ex, 2^(ex+1))
    if (ex < -14) ex = -14;  // subnormal: quantum 2^-24
    const double scaled = std::ldexp(a, 10 - ex);  // exact
    // The magnitude rounds up for RU of a positive and RD of a negative x, down for the
    // other directed cases.
    const bool mag_up = (mode > 0 && !sign) || (mode < 0 && sign);
    double m;
    if (mode == 0) m = std::nearbyint(scaled);  // ties to even (the default rounding mode)
    else m = mag_up ? std::ceil(scaled) : std::floor(scaled);
    if (m >= 2048.0) {
        m *= 0.5;
        ++ex;
    }
    if (ex > 15)  // beyond 65504 after rounding: infinity, or 65504 when rounding toward zero
        return uint16_t(sign | ((mode == 0 || mag_up) ? 0x7C00u : 0x7BFFu));
    const uint32_t mi = uint32_t(m);
    const uint32_t bits = mi < 1024u ? mi : ((uint32_t(ex + 15) << 10) | (mi - 1024u));
    return uint16_t(sign | bits);
}

inline double half_to_double(uint16_t h) {
    const uint32_t e = (h >> 10) & 0x1Fu, m = h & 0x3FFu;
    double v;
    if (e == 0) v = std::ldexp(double(m), -24);
    else if (e == 31) v = m ? std::nan("") : kInfinity;
    else v = std::ldexp(double(m | 0x400u), int(e) - 25);
    return (h & 0x8000u) ? -v : v;
}

inline uint16_t lane(uint32_t w, int i) { return uint16_t(w >> (16 * i)); }
inline uint32_t pair(uint16_t lo, uint16_t hi) { return uint32_t(lo) | (uint32_t(hi) << 16); }

}  // namespace fp16_host
#endif

#if defined(__CUDA_ARCH__)
namespace fp16_device {
/// A word as a half2 and back (register moves only).
__device__ __forceinline__ __half2 h2(uint32_t w) { return bit_cast_to<__half2>(w); }
__device__ __forceinline__ uint32_t bits(__half2 h) { return bit_cast_to<uint32_t>(h); }
}  // namespace fp16_device
#endif

/// RD(a * b + c) and RU(a * b + c), each rounded once (FFMA.RM / FFMA.RP).
CWBVH_HD CWBVH_INLINE float fma_rd(float a, float b, float c) {
#if defined(__CUDA_ARCH__)
    return __fmaf_rd(a, b, c);
#else
    return fp16_host::fma_down(a, b, c);
#endif
}
CWBVH_HD CWBVH_INLINE float fma_ru(float a, float b, float c) {
#if defined(__CUDA_ARCH__)
    return __fmaf_ru(a, b, c);
#else
    return fp16_host::float_directed(fp16_host::fma_round_to_odd(a, b, c), +1);
#endif
}

/// RD(a - b) and RU(a + b), each rounded once (FADD.RM / FADD.RP).
CWBVH_HD CWBVH_INLINE float sub_rd(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fsub_rd(a, b);
#else
    return fp16_host::fma_down(a, 1.0, -double(b));
#endif
}
CWBVH_HD CWBVH_INLINE float add_ru(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fadd_ru(a, b);
#else
    return fp16_host::float_directed(fp16_host::fma_round_to_odd(a, 1.0, b), +1);
#endif
}

/// (RN(lo), RN(hi)), low half first (F2FP.PACK_AB).
CWBVH_HD CWBVH_INLINE uint32_t h2_pack(float lo, float hi) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__floats2half2_rn(lo, hi));
#else
    return fp16_host::pair(fp16_host::half_from_double(lo, 0), fp16_host::half_from_double(hi, 0));
#endif
}
/// RD(x) or RU(x) as a half in both lanes (cvt.rm / cvt.rp.f16.f32; the broadcast is an
/// operand swizzle of the instruction that uses it).
CWBVH_HD CWBVH_INLINE uint32_t h2_broadcast_rd(float x) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__half2half2(__float2half_rd(x)));
#else
    return fp16_host::half_from_double(x, -1) * 0x00010001u;
#endif
}
CWBVH_HD CWBVH_INLINE uint32_t h2_broadcast_ru(float x) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__half2half2(__float2half_ru(x)));
#else
    return fp16_host::half_from_double(x, 1) * 0x00010001u;
#endif
}
/// The low or the high half of w in both lanes (an operand swizzle on the device).
CWBVH_HD CWBVH_INLINE uint32_t h2_lo(uint32_t w) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__low2half2(fp16_device::h2(w)));
#else
    return (w & 0xFFFFu) * 0x00010001u;
#endif
}
CWBVH_HD CWBVH_INLINE uint32_t h2_hi(uint32_t w) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__high2half2(fp16_device::h2(w)));
#else
    return (w >> 16) * 0x00010001u;
#endif
}
/// Lane-wise RN(a * b + c), rounded once (HFMA2).
CWBVH_HD CWBVH_INLINE uint32_t h2_fma(uint32_t a, uint32_t b, uint32_t c) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__hfma2(fp16_device::h2(a), fp16_device::h2(b), fp16_device::h2(c)));
#else
    using namespace fp16_host;
    uint16_t r[2];
    for (int i = 0; i < 2; ++i)
        r[i] = half_from_double(
            fma_round_to_odd(half_to_double(lane(a, i)), half_to_double(lane(b, i)), half_to_double(lane(c, i))), 0);
    return pair(r[0], r[1]);
#endif
}
/// Lane-wise minimum (HMNMX2; no NaN operands here; -0 counts below +0, as in PTX min).
CWBVH_HD CWBVH_INLINE uint32_t h2_min(uint32_t a, uint32_t b) {
#if defined(__CUDA_ARCH__)
    return fp16_device::bits(__hmin2(fp16_device::h2(a), fp16_device::h2(b)));
#else
    using namespace fp16_host;
    uint16_t r[2];
    // PTX min: (a < b) ? a : b with -0 < +0, so min(+0, -0) is -0 either way round.
    for (int i = 0; i < 2; ++i) {
        const uint16_t x = lane(a, i), y = lane(b, i);
        const double dx = half_to_double(x), dy = half_to_double(y);
        r[i] = dy < dx || (dy == dx && (y & 0x8000u) != 0) ? y : x;
    }
    return pair(r[0], r[1]);
#endif
}
/// Lane-wise a <= b as IEEE halves (one HSETP2 writing two predicates).
CWBVH_HD CWBVH_INLINE void h2_le(uint32_t a, uint32_t b, bool& lo, bool& hi) {
#if defined(__CUDA_ARCH__)
    uint32_t p, q;
    asm("{ .reg .pred p, q; setp.le.f16x2 p|q, %2, %3; selp.u32 %0, 1, 0, p; selp.u32 %1, 1, 0, q; }"
        : "=r"(p), "=r"(q)
        : "r"(a), "r"(b));
    lo = p != 0;
    hi = q != 0;
#else
    using namespace fp16_host;
    lo = half_to_double(lane(a, 0)) <= half_to_double(lane(b, 0));
    hi = half_to_double(lane(a, 1)) <= half_to_double(lane(b, 1));
#endif
}
#if !defined(__CUDA_ARCH__)
namespace fp16_host {
/// Per signed 16-bit lane: init folded with the lanes of a, b and c by `better` (which
/// of two values to keep).
template <class Better>
inline uint32_t fold3_s16x2(uint32_t a, uint32_t b, uint32_t c, int init, Better better) {
    const uint32_t w[3] = {a, b, c};
    uint32_t r = 0;
    for (int i = 0; i < 2; ++i) {
        int m = init;
        for (int k = 0; k < 3; ++k) {
            const int v = int16_t(uint16_t(w[k] >> (16 * i)));
            m = better(v, m) ? v : m;
        }
        r |= uint32_t(uint16_t(m)) << (16 * i);
    }
    return r;
}
/// max(a, b, c) for any ordered type (the DPX functions' host form).
template <class T>
inline T max3(T a, T b, T c) {
    const T m = a > b ? a : b;
    return m > c ? m : c;
}
}  // namespace fp16_host
#endif

/// Lane-wise max(0, a, b, c) and min(a, b, c) of signed 16-bit integers (sm_90 DPX: one
/// instruction each).
CWBVH_HD CWBVH_INLINE uint32_t vimax3_s16x2_relu(uint32_t a, uint32_t b, uint32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimax3_s16x2_relu(a, b, c);
#else
    return fp16_host::fold3_s16x2(a, b, c, 0, [](int v, int m) { return v > m; });
#endif
}
CWBVH_HD CWBVH_INLINE uint32_t vimin3_s16x2(uint32_t a, uint32_t b, uint32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimin3_s16x2(a, b, c);
#else
    return fp16_host::fold3_s16x2(a, b, c, 32767, [](int v, int m) { return v < m; });
#endif
}
/// Unsigned max of three, and signed max(0, a, b, c) (sm_90 DPX: one instruction each).
CWBVH_HD CWBVH_INLINE uint32_t umax3(uint32_t a, uint32_t b, uint32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimax3_u32(a, b, c);
#else
    return fp16_host::max3(a, b, c);
#endif
}
CWBVH_HD CWBVH_INLINE int32_t imax3_relu(int32_t a, int32_t b, int32_t c) {
#if defined(__CUDA_ARCH__)
    return __vimax3_s32_relu(a, b, c);
#else
    return fp16_host::max3(fp16_host::max3(a, b, c), 0, 0);
#endif
}

}  // namespace cwbvh
