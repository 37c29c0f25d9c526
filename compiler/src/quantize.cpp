// Conservative child box quantization for the 80-byte CWBVH node (Ylitie,
// Karras, Laine 2017, section 3.3: "Bounding box quantization").
//
// Rules (normative in spirit: they are stated purely in terms of the decode
// the traversal uses, node_decode.h decode_plane(p, e, q) = RN_f32(p + 2^(e-127) q)):
//  * Origin: p[a] = lo[a] of the union of the used child boxes (a float, so
//    exact). Every child satisfies p <= child.lo.
//  * Exponent: e[a] = the smallest biased exponent in [1, 254] with
//    decode_plane(p, e, 255) >= hi[a] (hi = union hi). Found from frexp() of the
//    double extent (hi - p)/255, then corrected by at most a few decode checks,
//    never from ceil(log2f()) (which is one too small just above 255 * 2^k and
//    makes q_hi = 256 wrap to 0). A zero extent gives e = 1 (the smallest
//    encodable exponent) and q = 0. Tiny extents clamp to e = 1 (still
//    conservative: the grid is just finer than needed). If decode_plane(p, e,
//    255) is not finite, or no e <= 254 reaches hi, the node is rejected (the
//    importer's |x| <= 2^125 limit keeps this from happening).
//  * Planes: q_hi = the smallest q in [0, 255] with decode(q) >= child.hi
//    (rounding up: the decoded box must contain the child); q_lo = the largest
//    q in [0, q_hi] with decode(q) <= child.lo (rounding down, same reason).
//    Both exist because decode(0) = p <= child.lo and decode(255) >= hi >=
//    child.hi; the estimate floor/ceil((x - p) * 2^-(e-127)) in double is only
//    a starting point, corrected by decode checks, so double rounding can
//    never make a plane non-conservative. q_lo <= q_hi keeps the integer box
//    non-inverted even where p + q*2^e rounds to the same float for several q.
#include "cwbvh/compiler/quantize.h"

#include <cmath>

#include "cwbvh/format/node_decode.h"

namespace cwbvh::compiler {

namespace {
constexpr int kMinBiased = 1;
constexpr int kMaxBiased = 254;

float decode(float p, int e, int q) { return decode_plane(p, uint8_t(e), uint8_t(q)); }
}  // namespace

bool choose_exponent(float p, float hi, uint8_t& e_out) {
    // decode(p, e, 255) is non-decreasing in e (255 * 2^(e-127) grows, RN is
    // monotone), so "smallest e with decode >= hi" is well defined.
    const double extent = double(hi) - double(p);  // rounding error is fixed below
    int e = kMinBiased;
    if (extent > 0.0) {
        // Smallest t with 2^t >= extent/255: extent/255 = f * 2^k, f in [0.5, 1).
        int k = 0;
        const double f = std::frexp(extent / 255.0, &k);
        const int t = f == 0.5 ? k - 1 : k;
        e = t + 127;
        if (e < kMinBiased) e = kMinBiased;
        if (e > kMaxBiased) e = kMaxBiased;
    }
    while (e > kMinBiased && decode(p, e - 1, 255) >= hi) --e;
    while (!(decode(p, e, 255) >= hi)) {
        if (e == kMaxBiased) return false;
        ++e;
    }
    const float top = decode(p, e, 255);
    if (!std::isfinite(top) || !std::isfinite(exponent_scale(uint8_t(e)) * 255.0f)) return false;
    e_out = uint8_t(e);
    return true;
}

void quantize_interval(float p, uint8_t e, float lo, float hi, uint8_t& q_lo_out, uint8_t& q_hi_out) {
    const double inv_scale = std::ldexp(1.0, 127 - int(e));  // 2^-(e-127), exact
    // Upper plane: start at ceil of the double estimate, then correct so that
    // q_hi is the smallest q with decode(q) >= hi (must round up).
    double est = std::ceil((double(hi) - double(p)) * inv_scale);
    int q_hi = est < 0.0 ? 0 : est > 255.0 ? 255 : int(est);
    while (q_hi < 255 && decode(p, e, q_hi) < hi) ++q_hi;
    while (q_hi > 0 && decode(p, e, q_hi - 1) >= hi) --q_hi;
    // Lower plane: largest q <= q_hi with decode(q) <= lo (must round down).
    est = std::floor((double(lo) - double(p)) * inv_scale);
    int q_lo = est < 0.0 ? 0 : est > double(q_hi) ? q_hi : int(est);
    while (q_lo > 0 && decode(p, e, q_lo) > lo) --q_lo;
    while (q_lo < q_hi && decode(p, e, q_lo + 1) <= lo) ++q_lo;
    q_lo_out = uint8_t(q_lo);
    q_hi_out = uint8_t(q_hi);
}

Result quantize_node(const Aabb (&boxes)[8], uint8_t used, CwbvhNode& node) {
    if (used == 0) return Result::fail(Status::kInternal, 0, "quantize: node without children");
    Aabb frame;
    for (int s = 0; s < kWidth; ++s) {
        if (!(used >> s & 1)) continue;
        const Aabb& b = boxes[s];
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a]) || !(b.lo[a] <= b.hi[a])) {
                return Result::fail(Status::kInternal, 0, "quantize: child box with an empty or non-finite axis");
            }
        }
        frame.grow(b);
    }
    for (int a = 0; a < 3; ++a) {
        node.p[a] = frame.lo[a];
        if (!choose_exponent(frame.lo[a], frame.hi[a], node.e[a])) {
            return Result::fail(Status::kInternal, 0,
                                "quantize: box extent " + std::to_string(double(frame.hi[a]) - double(frame.lo[a])) +
                                    " at " + std::to_string(frame.lo[a]) +
                                    " cannot be encoded (exponent out of range)");
        }
        for (int s = 0; s < kWidth; ++s) {
            node.q_lo[a][s] = 0;
            node.q_hi[a][s] = 0;
            if (!(used >> s & 1)) continue;
            quantize_interval(node.p[a], node.e[a], boxes[s].lo[a], boxes[s].hi[a], node.q_lo[a][s],
                              node.q_hi[a][s]);
        }
    }
    return Result::success();
}

Aabb decode_child_box(const CwbvhNode& node, int slot) {
    Aabb b;
    decode_slot_box(node, slot, b.lo.data(), b.hi.data());
    return b;
}

}  // namespace cwbvh::compiler
