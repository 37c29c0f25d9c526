// Child box quantization of the 80-byte CWBVH node (Ylitie et al. 2017,
// section 3.3), made conservative under the normative decode
// (node_decode.h: decode_plane = RN_f32(p + 2^(e-127) * q)).
#pragma once

#include <cstdint>
#include <string>

#include "cwbvh/format/status.h"
#include "cwbvh/compiler/model.h"

namespace cwbvh::compiler {

/// Smallest biased exponent e in [1, 254] with decode_plane(p, e, 255) >= hi,
/// for p <= hi finite. A zero extent (hi == p) gives e = 1. Returns false when
/// no e in range works or 2^(e-127) * 255 overflows / decodes to infinity.
[[nodiscard]] bool choose_exponent(float p, float hi, uint8_t& e);

/// For p <= lo <= hi and decode_plane(p, e, 255) >= hi:
///   q_hi = smallest q in [0, 255] with decode_plane(p, e, q) >= hi,
///   q_lo = largest q in [0, q_hi] with decode_plane(p, e, q) <= lo.
/// Both exist (decode(0) = p <= lo); q_lo <= q_hi.
void quantize_interval(float p, uint8_t e, float lo, float hi, uint8_t& q_lo, uint8_t& q_hi);

/// Fills p, e, q_lo, q_hi of `node` for the children in slots with bit s of
/// `used` set (boxes[s]); unused slots get q = 0. The origin p is the lo
/// corner of the union of the used child boxes. Errors: no used slot,
/// empty or non-finite child box, exponent out of range / overflow.
Result quantize_node(const Aabb (&boxes)[8], uint8_t used, CwbvhNode& node);

/// The decoded (quantized) box of slot s of an encoded node.
Aabb decode_child_box(const CwbvhNode& node, int slot);

}  // namespace cwbvh::compiler
