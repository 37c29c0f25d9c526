// Decoding of CWBVH node fields, shared by the compiler's verifier, the
// validator, the CPU reference traversal and the CUDA kernels.
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"

namespace cwbvh {

/// 2^(e-127) for a biased exponent e in 1..254 (exact; the bit pattern e<<23).
CWBVH_HD CWBVH_INLINE float exponent_scale(uint8_t e) {
    uint32_t bits = uint32_t(e) << 23;
    float f;
    memcpy(&f, &bits, sizeof f);
    return f;
}

/// The normative decode of one quantized plane: RN_f32(p + 2^(e-127) * q).
/// The product is exact for q <= 255 and e in 1..254 unless it overflows,
/// which a valid file never makes happen for planes in use.
/// Written as one explicit fma so the result is the same on every compiler,
/// with or without contraction (the product is exact, so fma == mul+add).
/// The same with the byte q given as a float (exact: 0..255), as the node tests hold it.
CWBVH_HD CWBVH_INLINE float decode_plane_qf(float p, uint8_t e, float qf) {
#if defined(__CUDA_ARCH__)
    return __fmaf_rn(exponent_scale(e), qf, p);
#else
    return __builtin_fmaf(exponent_scale(e), qf, p);
#endif
}
CWBVH_HD CWBVH_INLINE float decode_plane(float p, uint8_t e, uint8_t q) { return decode_plane_qf(p, e, float(q)); }

/// The decoded box of one slot: lo/hi[a] = decode_plane of q_lo/q_hi (the
/// box the traversal tests; every consumer decodes through this).
CWBVH_HD CWBVH_INLINE void decode_slot_box(const CwbvhNode& n, int slot, float lo[3], float hi[3]) {
    for (int a = 0; a < 3; ++a) {
        lo[a] = decode_plane(n.p[a], n.e[a], n.q_lo[a][slot]);
        hi[a] = decode_plane(n.p[a], n.e[a], n.q_hi[a][slot]);
    }
}

/// Meta byte helpers (spec: "meta byte").
CWBVH_HD CWBVH_INLINE bool meta_is_empty(uint8_t m) { return m == kMetaEmpty; }
CWBVH_HD CWBVH_INLINE bool meta_is_internal(uint8_t m) { return (m & 0x1F) >= 24 && (m >> 5) == 1; }
CWBVH_HD CWBVH_INLINE bool meta_is_leaf(uint8_t m) { return m != kMetaEmpty && (m & 0x1F) < 24; }
/// Triangle count of a leaf meta byte (unary in bits 5..7): 1, 2 or 3; 0 if malformed.
CWBVH_HD CWBVH_INLINE int meta_leaf_count(uint8_t m) {
    switch (m >> 5) { case 1: return 1; case 3: return 2; case 7: return 3; default: return 0; }
}
CWBVH_HD CWBVH_INLINE int meta_leaf_offset(uint8_t m) { return m & 0x1F; }
CWBVH_HD CWBVH_INLINE uint8_t make_meta_internal(int slot) { return uint8_t(0x20 | (24 + slot)); }
CWBVH_HD CWBVH_INLINE uint8_t make_meta_leaf(int count, int offset) {
    const uint8_t unary = count == 1 ? 1 : count == 2 ? 3 : 7;
    return uint8_t((unary << 5) | offset);
}

/// Index in NODE of the internal child in `slot`: child_base + number of
/// internal slots below it (internal children are stored contiguously in slot order).
CWBVH_HD CWBVH_INLINE uint32_t internal_child_index(const CwbvhNode& n, int slot) {
    const uint32_t below = uint32_t(n.imask) & ((1u << slot) - 1u);
#if defined(__CUDA_ARCH__)
    return n.child_base + uint32_t(__popc(below));
#else
    return n.child_base + uint32_t(__builtin_popcount(below));
#endif
}

}  // namespace cwbvh
