// The bits of a value as another type of the same size, host and device: the one home of
// the float <-> bit pattern moves (kernels/.../fp.h and format/float_round.h use these).
#pragma once

#include <cstdint>
#include <cstring>

#include "cwbvh/format/hostdevice.h"

namespace cwbvh {

/// The bits of `from` as a To of the same size (memcpy: no aliasing rule broken; a
/// register move after optimization).
template <class To, class From>
CWBVH_HD CWBVH_INLINE To bit_cast_to(const From& from) {
    static_assert(sizeof(To) == sizeof(From), "bit_cast_to: sizes differ");
    To to;
    memcpy(&to, &from, sizeof to);
    return to;
}
CWBVH_HD CWBVH_INLINE uint32_t float_to_bits(float f) { return bit_cast_to<uint32_t>(f); }
CWBVH_HD CWBVH_INLINE float bits_to_float(uint32_t u) { return bit_cast_to<float>(u); }

}  // namespace cwbvh
