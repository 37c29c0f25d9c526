// Floating-point and bit helpers shared by host and device traversal code.
// Only <cstdint>/<cstring>-level facilities; every function is CWBVH_HD.
//
// Contraction rule: code that relies on two expressions rounding the same way
// (the watertight edge functions, Woop et al. 2013) uses mul_rn/add_rn/sub_rn.
// On the device these are the __fmul_rn/__fadd_rn intrinsics, which nvcc never
// fuses into an fma. On the host they are plain operators, so host code must be
// compiled with -ffp-contract=off (GCC's default in ISO mode, CMAKE_CXX_EXTENSIONS
// OFF; kernels/CMakeLists.txt also sets it on every target that uses these headers).
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/bits.h"
#include "cwbvh/format/hostdevice.h"

/// Full unrolling of small constant loops in device code, so that arrays indexed by
/// the loop variable stay in registers (host compilers decide for themselves).
#if defined(__CUDA_ARCH__)
#define CWBVH_UNROLL _Pragma("unroll")
/// A loop kept rolled in device code (a rare path whose unrolled copies would only cost
/// code size; its body must not index register arrays with the loop variable).
#define CWBVH_NO_UNROLL _Pragma("unroll 1")
#else
#define CWBVH_UNROLL
#define CWBVH_NO_UNROLL
#endif

namespace cwbvh {

inline constexpr float kInfinity = __builtin_huge_valf();
inline constexpr float kFloatMin = 1.17549435e-38f;  ///< FLT_MIN = 2^-126

// bit_cast_to, float_to_bits, bits_to_float: cwbvh/format/bits.h (included above).
/// True for NaN. Written on the bits so that no compiler flag can fold it away.
CWBVH_HD CWBVH_INLINE bool is_nan_f(float x) { return (float_to_bits(x) & 0x7FFFFFFFu) > 0x7F800000u; }
/// True for every value except +-inf and NaN.
CWBVH_HD CWBVH_INLINE bool is_finite_f(float x) { return (float_to_bits(x) & 0x7F800000u) != 0x7F800000u; }
/// x is finite and not +-0: the bits of |x| lie in [1, FLT_MAX's] (one subtraction, one compare).
CWBVH_HD CWBVH_INLINE bool is_finite_nonzero_f(float x) { return (float_to_bits(x) & 0x7FFFFFFFu) - 1u < 0x7F7FFFFFu; }
CWBVH_HD CWBVH_INLINE float abs_f(float x) { return bits_to_float(float_to_bits(x) & 0x7FFFFFFFu); }
CWBVH_HD CWBVH_INLINE double abs_d(double x) { return x < 0 ? -x : x; }
/// min/max for non-NaN operands (the traversal never feeds them NaN: see node_intersect.h).
/// On the device one FMNMX instruction (fminf/fmaxf); the ternary form costs a
/// compare and a select, because it must return `a` when b is NaN. For non-NaN
/// operands both forms return the same value up to the sign of a zero result, which
/// no caller can see (they compare with <= or feed products that stay zero).
CWBVH_HD CWBVH_INLINE float min_f(float a, float b) {
#if defined(__CUDA_ARCH__)
    return fminf(a, b);
#else
    return b < a ? b : a;
#endif
}
CWBVH_HD CWBVH_INLINE float max_f(float a, float b) {
#if defined(__CUDA_ARCH__)
    return fmaxf(a, b);
#else
    return a < b ? b : a;
#endif
}

/// Correctly rounded (round-to-nearest-even) operations that are never contracted.
CWBVH_HD CWBVH_INLINE float mul_rn(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fmul_rn(a, b);
#else
    return a * b;
#endif
}
CWBVH_HD CWBVH_INLINE float add_rn(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fadd_rn(a, b);
#else
    return a + b;
#endif
}
CWBVH_HD CWBVH_INLINE float sub_rn(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fsub_rn(a, b);
#else
    return a - b;
#endif
}
/// One fused multiply-add, rounded once (never split into a product and a sum).
CWBVH_HD CWBVH_INLINE float fma_rn(float a, float b, float c) {
#if defined(__CUDA_ARCH__)
    return __fmaf_rn(a, b, c);
#else
    return __builtin_fmaf(a, b, c);
#endif
}
/// |x| as an operand modifier on the device (fabsf: free in FADD/FFMA; fp.h's abs_f
/// works on the bits and costs a LOP3 there).
CWBVH_HD CWBVH_INLINE float abs_fm(float x) {
#if defined(__CUDA_ARCH__)
    return fabsf(x);
#else
    return abs_f(x);
#endif
}
CWBVH_HD CWBVH_INLINE double mul_rn(double a, double b) {
#if defined(__CUDA_ARCH__)
    return __dmul_rn(a, b);
#else
    return a * b;
#endif
}
CWBVH_HD CWBVH_INLINE double add_rn(double a, double b) {
#if defined(__CUDA_ARCH__)
    return __dadd_rn(a, b);
#else
    return a + b;
#endif
}
CWBVH_HD CWBVH_INLINE double sub_rn(double a, double b) {
#if defined(__CUDA_ARCH__)
    return __dsub_rn(a, b);
#else
    return a - b;
#endif
}

/// Index of the highest set bit (x != 0): PTX bfind / x86 bsr. On the device as bfind
/// itself (SASS FLO): written as 31 - __clz(x), nvcc emits FLO and then two subtractions
/// (31 - (31 - FLO)) that it does not fold, in every node and triangle step (issue 18).
CWBVH_HD CWBVH_INLINE int highest_bit(uint32_t x) {
#if defined(__CUDA_ARCH__)
    uint32_t b;
    asm("bfind.u32 %0, %1;" : "=r"(b) : "r"(x));
    return int(b);
#else
    return 31 - __builtin_clz(x);
#endif
}
CWBVH_HD CWBVH_INLINE int popcount32(uint32_t x) {
#if defined(__CUDA_ARCH__)
    return __popc(x);
#else
    // Bit trick, not __builtin_popcount: on baseline x86-64 (no -mpopcnt) that is a
    // call into libgcc.
    x = x - ((x >> 1) & 0x55555555u);
    x = (x & 0x33333333u) + ((x >> 2) & 0x33333333u);
    return int((((x + (x >> 4)) & 0x0F0F0F0Fu) * 0x01010101u) >> 24);
#endif
}

}  // namespace cwbvh
