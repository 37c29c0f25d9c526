// Directed rounding of doubles to floats, and the float neighbours: the one home for
// every bound that a double computation hands to float storage.
//
// Which way each caller must round (a bound rounded the wrong way by one float step
// lets a ray slip between the stored value and the exact one):
// - a lower bound (box min, clipped triangle part, instance world box) rounds down,
//   an upper bound up (compiler/src/clip.cpp, format/src/transform_host.cpp);
// - a segment's reach rounds away from the ray origin (kernels/.../axis_range.h);
// - the host emulation of the device's directed float operations rounds as the
//   instruction does (kernels/.../fp16.h).
//
// Host and device give the same results for every input, NaN included:
//   float_round_down(x) = the largest float <= x  (FLT_MAX < x < inf: FLT_MAX; x < -FLT_MAX: -inf)
//   float_round_up(x)   = the smallest float >= x (-inf < x < -FLT_MAX: -FLT_MAX; x > FLT_MAX: +inf)
//   +-inf -> +-inf; NaN -> -inf (down) and +inf (up): never a bound that excludes anything.
// On the device each is one conversion with the rounding mode in the instruction (PTX
// cvt.rm / cvt.rp.f32.f64, written out so that no build flag can add .ftz: with nvcc's
// -ftz=true or --use_fast_math the __double2float_rd/_ru intrinsics become cvt...ftz, which
// flushes a subnormal result to zero, inward for float_round_up(1e-40)); on the host a
// conversion to nearest and at most one step, with the range checked first (converting
// a double outside the float range is undefined behaviour in C++).
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/bits.h"
#include "cwbvh/format/hostdevice.h"

namespace cwbvh {

namespace float_round_detail {
inline constexpr double kFloatMax = 3.4028234663852886e38;  // FLT_MAX, exact in double
}  // namespace float_round_detail

/// The next float above f (IEEE 754 nextUp), by float bit arithmetic; equal to
/// std::nextafter(f, +inf) (tested against it). +-0 -> the least positive subnormal,
/// +inf stays +inf, -inf -> -FLT_MAX, NaN stays NaN.
CWBVH_HD CWBVH_INLINE float next_float_up(float f) {
    if (!(f == f) || f == __builtin_huge_valf()) return f;  // NaN, +inf
    if (f == 0.0f) return bits_to_float(1u);
    const uint32_t u = float_to_bits(f);
    return bits_to_float(f > 0.0f ? u + 1u : u - 1u);  // magnitude up / down
}
/// The next float below f (nextDown): the mirror of next_float_up.
CWBVH_HD CWBVH_INLINE float next_float_down(float f) {
    if (!(f == f) || f == -__builtin_huge_valf()) return f;  // NaN, -inf
    if (f == 0.0f) return bits_to_float(0x80000001u);
    const uint32_t u = float_to_bits(f);
    return bits_to_float(f > 0.0f ? u - 1u : u + 1u);
}

/// The largest float <= x (see the top of the file).
CWBVH_HD CWBVH_INLINE float float_round_down(double x) {
    if (!(x == x)) return -__builtin_huge_valf();
#if defined(__CUDA_ARCH__)
    float r;
    asm("cvt.rm.f32.f64 %0, %1;" : "=f"(r) : "d"(x));
    return r;
#else
    if (x > float_round_detail::kFloatMax && x < __builtin_huge_val()) return float(float_round_detail::kFloatMax);
    if (x < -float_round_detail::kFloatMax) return -__builtin_huge_valf();
    const float f = static_cast<float>(x);  // to nearest (+inf stays): at most one step above x
    return static_cast<double>(f) > x ? next_float_down(f) : f;
#endif
}
/// The smallest float >= x (see the top of the file).
CWBVH_HD CWBVH_INLINE float float_round_up(double x) {
    if (!(x == x)) return __builtin_huge_valf();
#if defined(__CUDA_ARCH__)
    float r;
    asm("cvt.rp.f32.f64 %0, %1;" : "=f"(r) : "d"(x));
    return r;
#else
    if (x < -float_round_detail::kFloatMax && x > -__builtin_huge_val()) return -float(float_round_detail::kFloatMax);
    if (x > float_round_detail::kFloatMax) return __builtin_huge_valf();
    const float f = static_cast<float>(x);
    return static_cast<double>(f) < x ? next_float_up(f) : f;
#endif
}

}  // namespace cwbvh
