// kernels/src/cpu_trace.cpp compiles the CPU traversal twice on x86-64 (target_clones: FMA
// hardware and the baseline, whose fmaf is a libm call), and claims both give the same bits:
// an fma rounds once either way. This checks the claim at its root, on the operand classes
// the traversal feeds its fmas (cancellation, huge and tiny magnitudes, subnormal results,
// zeros of both signs, infinities); the traversal-level check is the warp model's (baseline
// code) bitwise agreement with the CPU reference (the FMA clone on an FMA machine).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>

namespace {

__attribute__((noinline)) float fma_baseline(float a, float b, float c) { return __builtin_fmaf(a, b, c); }

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
__attribute__((noinline, target("fma"))) float fma_hardware(float a, float b, float c) {
    return __builtin_fmaf(a, b, c);
}
#endif

uint32_t bits(float f) {
    uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    return u;
}

TEST(FmaClones, LibmAndHardwareFmaGiveTheSameBits) {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
    if (!__builtin_cpu_supports("fma")) GTEST_SKIP() << "this CPU has no FMA: only the baseline clone runs here";
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> exp(-140, 120);
    std::uniform_real_distribution<float> mant(1.0f, 2.0f);
    auto any = [&] {
        const float m = std::ldexp(mant(rng), exp(rng));
        return (rng() & 1) ? -m : m;
    };
    size_t checked = 0, mismatches = 0;
    for (int i = 0; i < 2000000; ++i) {
        float a = any(), b = any(), c = any();
        switch (i % 5) {
            case 0: c = -a * b; break;                       // cancellation: the rounded product
            case 1: c = std::nextafter(-a * b, 0.0f); break; // ... one ulp off
            case 2: b = (rng() & 1) ? 1.0f : 0.0f; break;    // the shear rows' exact 1 and 0
            case 3: a = std::ldexp(a, -100); break;          // subnormal products
            default: break;
        }
        const float x = fma_baseline(a, b, c), y = fma_hardware(a, b, c);
        ++checked;
        if (bits(x) != bits(y) && !(std::isnan(x) && std::isnan(y))) ++mismatches;
    }
    const float specials[] = {0.0f, -0.0f, INFINITY, -INFINITY, 1e-45f, -1e-45f, 3.4e38f, -3.4e38f, 1.0f};
    for (float a : specials)
        for (float b : specials)
            for (float c : specials) {
                const float x = fma_baseline(a, b, c), y = fma_hardware(a, b, c);
                ++checked;
                if (bits(x) != bits(y) && !(std::isnan(x) && std::isnan(y))) ++mismatches;
            }
    EXPECT_EQ(mismatches, 0u) << "of " << checked;
#else
    GTEST_SKIP() << "no target clones on this compiler or architecture";
#endif
}

}  // namespace
