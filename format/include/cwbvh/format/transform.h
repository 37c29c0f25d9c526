// Affine 3x4 transforms of two-level scenes (format 1.2, spec 3.10): the one
// home of the arithmetic that moves points and directions between world and
// object space. Host and device.
//
// Rounding (normative for the traversal, spec 3.10): each output component is
// evaluated as fma(m0, x, fma(m1, y, fma(m2, z, m3))) for a point and
// fma(m0, x, fma(m1, y, m2 * z)) for a direction, in f32, in that order, so the
// CPU reference and the CUDA kernels move a ray to the same object-space ray
// bit for bit. A hit's t is measured in the object-space ray's parameter, which
// equals the world ray's parameter (the map is affine; d is not renormalized).
#pragma once
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/format/format.h"

namespace cwbvh {

/// One fused multiply-add, rounded once (the device intrinsic is never split).
CWBVH_HD CWBVH_INLINE float transform_fma(float a, float b, float c) {
#if defined(__CUDA_ARCH__)
    return __fmaf_rn(a, b, c);
#else
    return __builtin_fmaf(a, b, c);
#endif
}

CWBVH_HD CWBVH_INLINE void transform_point(const float m[3][4], const float p[3], float out[3]) {
    for (int r = 0; r < 3; ++r)
        out[r] = transform_fma(m[r][0], p[0], transform_fma(m[r][1], p[1], transform_fma(m[r][2], p[2], m[r][3])));
}

CWBVH_HD CWBVH_INLINE void transform_vector(const float m[3][4], const float v[3], float out[3]) {
    for (int r = 0; r < 3; ++r)
        out[r] = transform_fma(m[r][0], v[0], transform_fma(m[r][1], v[1], m[r][2] * v[2]));
}

}  // namespace cwbvh
