// Box4 (compiler/include/cwbvh/compiler/box4.h) against the scalar code it
// replaces in the SBVH's binning: merge() is std::min/std::max and grow() is
// Aabb::grow, bit for bit (signed zeros, infinities, empty boxes), and
// half_area() is Aabb::half_area().
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "cwbvh/compiler/box4.h"

namespace cwbvh::compiler {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

void scalar_merge(Aabb& a, const Aabb& b) {
    for (int j = 0; j < 3; ++j) {
        a.lo[j] = std::min(a.lo[j], b.lo[j]);
        a.hi[j] = std::max(a.hi[j], b.hi[j]);
    }
}

bool same_bits(const Aabb& a, const Aabb& b) { return std::memcmp(&a, &b, sizeof(Aabb)) == 0; }

/// Values where the order of a min/max matters: both zeros, infinities, ties.
float pick(std::mt19937& rng) {
    static const float special[] = {0.0f, -0.0f, 1.0f, -1.0f, kInf, -kInf, 1e-38f, -1e-38f, 3.5f};
    std::uniform_int_distribution<int> which(0, 11);
    const int w = which(rng);
    if (w < 9) return special[w];
    return std::uniform_real_distribution<float>(-4.0f, 4.0f)(rng);
}

TEST(Box4, MergeGrowAndAreaAreTheScalarCodeBitForBit) {
    std::mt19937 rng(7);
    for (int trial = 0; trial < 2000; ++trial) {
        Aabb scalar, grown;
        Box4 vec, vgrown;
        const int n = 1 + trial % 9;
        for (int i = 0; i < n; ++i) {
            Aabb b;
            for (int j = 0; j < 3; ++j) {
                b.lo[j] = pick(rng);
                b.hi[j] = pick(rng);  // may be below lo: an empty box, as empty bins are
            }
            scalar_merge(scalar, b);
            vec.merge(Box4::of(b));
            ASSERT_TRUE(same_bits(vec.aabb(), scalar)) << "trial " << trial << " box " << i;
            ASSERT_EQ(vec.empty(), scalar.empty());
            const double hs = scalar.half_area(), hv = vec.half_area();
            ASSERT_TRUE(std::memcmp(&hs, &hv, sizeof(double)) == 0 || (std::isnan(hs) && std::isnan(hv)));

            const Vec3 p{b.lo[0], b.lo[1], b.hi[2]};
            grown.grow(p);
            vgrown.grow(F4{p[0], p[1], p[2], p[2]});
            ASSERT_TRUE(same_bits(vgrown.aabb(), grown)) << "trial " << trial << " point " << i;
        }
    }
}

TEST(Box4, SignedZeroTiesKeepTheScalarWinner) {
    // std::min(+0, -0) is +0 (the first), Aabb::grow takes the point on a tie.
    Aabb a;
    a.lo = {0.0f, -0.0f, 0.0f};
    a.hi = {0.0f, -0.0f, -0.0f};
    Aabb b;
    b.lo = {-0.0f, 0.0f, 0.0f};
    b.hi = {-0.0f, 0.0f, 0.0f};
    Aabb s = a;
    scalar_merge(s, b);
    Box4 v = Box4::of(a);
    v.merge(Box4::of(b));
    EXPECT_TRUE(same_bits(v.aabb(), s));
    EXPECT_FALSE(std::signbit(v.aabb().lo[0]));
    EXPECT_TRUE(std::signbit(v.aabb().lo[1]));
}

}  // namespace
}  // namespace cwbvh::compiler
