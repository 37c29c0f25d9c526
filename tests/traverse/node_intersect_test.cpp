// intersect_node never misses a child box that the exact ray segment touches
// (conservative, Ize 2013 style), on random and adversarial nodes and rays.
#include <gtest/gtest.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "cwbvh/kernels/fast_node_pairs.h"
#include "cwbvh/kernels/node_intersect.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/oracle/oracle.h"
#include "traverse/test_scenes.h"

namespace cwbvh::test {
namespace {

// Exact: does {o + t d : tmin <= t <= tmax, |t| <= 2^128} touch the closed box [lo, hi]?
// (A hit whose t rounds beyond the float range is no hit: spec/rays.md.) Slab intervals are
// compared as fractions with expansion arithmetic (oracle.h).
bool exact_box_hit(const float* lo, const float* hi, const Ray& r) {
    // For each bounded axis: t0 = N0/|d|, t1 = N1/|d| with N = (plane - o) * sign(d).
    struct Frac {
        Exact2 num;  // exact plane - o, sign-adjusted
        float den;   // |d| > 0
    };
    Frac t0[3], t1[3];
    int n = 0;
    for (int a = 0; a < 3; ++a) {
        if (r.dir[a] == 0.0f) {
            if (!(lo[a] <= r.org[a] && r.org[a] <= hi[a])) return false;
            continue;
        }
        Exact2 dl = exact_diff(lo[a], r.org[a]), dh = exact_diff(hi[a], r.org[a]);
        if (r.dir[a] < 0) {
            std::swap(dl, dh);
            dl = {-dl.h, -dl.l};
            dh = {-dh.h, -dh.l};
        }
        t0[n] = {dl, std::fabs(r.dir[a])};
        t1[n] = {dh, std::fabs(r.dir[a])};
        ++n;
    }
    // a/b <= c/d  <=>  a*d - c*b <= 0 (b, d > 0).
    auto le = [](const Frac& x, const Frac& y) {
        Expansion e;
        double p, q;
        two_prod(x.num.h, double(y.den), p, q);
        e.add(p);
        e.add(q);
        two_prod(x.num.l, double(y.den), p, q);
        e.add(p);
        e.add(q);
        two_prod(-y.num.h, double(x.den), p, q);
        e.add(p);
        e.add(q);
        two_prod(-y.num.l, double(x.den), p, q);
        e.add(p);
        e.add(q);
        return e.sign() <= 0;
    };
    const double two128 = std::ldexp(1.0, 128);
    const double tmin = std::max(double(r.tmin), -two128), tmax = std::min(double(r.tmax), two128);
    const Frac fmin{{tmin, 0.0}, 1.0f}, fmax{{tmax, 0.0}, 1.0f};
    for (int i = 0; i < n; ++i) {
        if (!le(fmin, t1[i])) return false;
        if (!le(t0[i], fmax)) return false;
        for (int j = 0; j < n; ++j)
            if (!le(t0[i], t1[j])) return false;
    }
    return r.tmin <= r.tmax;
}

struct Gen {
    std::mt19937_64 rng;
    explicit Gen(uint64_t seed) : rng(seed) {}
    int irange(int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); }
    float uni(float a, float b) { return std::uniform_real_distribution<float>(a, b)(rng); }
    bool coin(double p = 0.5) { return std::bernoulli_distribution(p)(rng); }
};

// A random node at scale 2^k: 8 slots (some empty, some internal, leaves otherwise),
// some flat children (qlo == qhi) and full-range ones.
CwbvhNode random_node(Gen& g, int k) {
    CwbvhNode n{};
    const float scale = std::ldexp(1.0f, k);
    for (int a = 0; a < 3; ++a) {
        n.p[a] = g.uni(-4, 4) * scale;
        n.e[a] = uint8_t(std::clamp(127 + k - 8 + g.irange(-2, 2), 1, 254));
        if (g.coin(0.05)) n.e[a] = 1;  // flat axis: tiny exponent
    }
    int tri_off = 0;
    for (int s = 0; s < 8; ++s) {
        const int kind = g.irange(0, 5);  // 0 empty, 1-2 internal, 3-5 leaf
        if (kind == 0) continue;
        if (kind <= 2) {
            n.meta[s] = make_meta_internal(s);
            n.imask |= uint8_t(1u << s);
        } else {
            n.meta[s] = make_meta_leaf(1, tri_off++);
        }
        for (int a = 0; a < 3; ++a) {
            int lo = g.irange(0, 255), hi = g.irange(0, 255);
            if (lo > hi) std::swap(lo, hi);
            if (g.coin(0.15)) hi = lo;              // flat
            if (g.coin(0.05)) lo = 0, hi = 255;     // full
            n.q_lo[a][s] = uint8_t(lo);
            n.q_hi[a][s] = uint8_t(hi);
        }
    }
    return n;
}

// extreme: also subnormal and huge components (no fast test for most such rays).
float random_dir_component(Gen& g, bool extreme) {
    switch (g.irange(0, extreme ? 11 : 9)) {
        case 0: return 0.0f;
        case 1: return -0.0f;
        case 2: return float(g.irange(-3, 3));
        case 3: return g.uni(-1, 1) * std::ldexp(1.0f, g.irange(-40, -10));  // nearly axis-parallel
        case 10: return std::ldexp(g.uni(-1, 1), g.irange(-149, -124));        // subnormal: RN(1/d) overflows
        case 11: return std::ldexp(g.uni(-1, 1), g.irange(100, 127));           // huge: RN(1/d) tiny or subnormal
        default: return g.uni(-1, 1);
    }
}

// Child c's decoded box, and its bits in a hit mask (internal: 24 + (c ^ octinv);
// a leaf: the bit of its first triangle).
void child_box(const CwbvhNode& n, int c, float lo[3], float hi[3]) {
    for (int a = 0; a < 3; ++a) {
        lo[a] = decode_plane(n.p[a], n.e[a], n.q_lo[a][c]);
        hi[a] = decode_plane(n.p[a], n.e[a], n.q_hi[a][c]);
    }
}
uint32_t child_bit(const CwbvhNode& n, int c, uint32_t octinv) {
    return ((n.imask >> c) & 1u) ? (1u << (24 + (c ^ octinv))) : (1u << (n.meta[c] & 0x1F));
}

// Which node test check_never_misses runs.
enum class Which { kReference, kFast };

// The contract on random nodes and rays aimed at a random child: every child whose
// decoded box the exact segment touches has its bits set. kFast: intersect_node_fast
// with the node's own NodeScale, on the rays fast_node_test_applies accepts (tmin -0
// made +0 as the lane does); also rays with tmin > 0.
void check_never_misses(Which which, uint64_t seed) {
    Gen g(seed);
    uint64_t fast_rays = 0, rays = 0, ref_extra = 0;  // ref_extra: the reference test's on the same rays
    uint64_t tested = 0, exact_hits = 0, misses = 0, extra = 0;
    for (int iter = 0; iter < 60000; ++iter) {
        const int k = g.coin(0.2) ? g.irange(-60, 60) : g.irange(-4, 4);
        const CwbvhNode n = random_node(g, k);
        // Pick a target: a decoded corner, face point or interior point of a random
        // non-empty slot; aim at it from a random origin, or start on/inside the box.
        int s = g.irange(0, 7);
        for (int t = 0; t < 8 && n.meta[s] == 0; ++t) s = (s + 1) & 7;
        if (n.meta[s] == 0) continue;
        float lo[3], hi[3], target[3];
        for (int a = 0; a < 3; ++a) {
            lo[a] = decode_plane(n.p[a], n.e[a], n.q_lo[a][s]);
            hi[a] = decode_plane(n.p[a], n.e[a], n.q_hi[a][s]);
            switch (g.irange(0, 3)) {
                case 0: target[a] = lo[a]; break;
                case 1: target[a] = hi[a]; break;
                case 2: target[a] = std::nextafter(hi[a], INFINITY); break;  // just outside
                default: target[a] = lo[a] + (hi[a] - lo[a]) * g.uni(0, 1); break;
            }
        }
        Ray r;
        for (int a = 0; a < 3; ++a) r.dir[a] = random_dir_component(g, which == Which::kReference);
        if (r.dir[0] == 0 && r.dir[1] == 0 && r.dir[2] == 0) r.dir[g.irange(0, 2)] = 1.0f;
        const int start = g.irange(0, 3);
        const float dist = std::ldexp(g.uni(0.5f, 8.0f), k);
        for (int a = 0; a < 3; ++a) {
            if (start == 0) r.org[a] = target[a];  // on the box (corner/face) or just outside
            else r.org[a] = target[a] - dist * r.dir[a];  // rounded: passes near the target
        }
        r.tmin = g.coin(0.8) ? 0.0f : -dist;
        if (which == Which::kFast && g.coin(0.3)) r.tmin = dist * g.uni(0.0f, 1.5f);  // the moved origin
        r.tmax = g.coin(0.6) ? INFINITY : (g.coin() ? 0.0f : dist * g.uni(0.5f, 2.0f));
        if (!ray_is_traceable(r)) continue;
        ++rays;
        NodeRay nr = make_node_ray(r);
        uint32_t mask = 0, ref_mask = 0;
        if (which == Which::kFast) {
            ref_mask = intersect_node(n, nr, r.tmin, r.tmax);
            const float tmin = r.tmin == 0.0f ? 0.0f : r.tmin;
            const NodeScale sc = node_scale(&n, 1);
            enable_fast_node_test(nr, sc, r.dir, tmin);
            if (!nr.uses_fast_test()) continue;
            ++fast_rays;
            mask = intersect_node_fast(n, nr, r.tmax, sc.frame_word);
        } else {
            mask = intersect_node(n, nr, r.tmin, r.tmax);
        }
        for (int c = 0; c < 8; ++c) {
            if (n.meta[c] == 0) continue;
            float clo[3], chi[3];
            child_box(n, c, clo, chi);
            const bool exact = exact_box_hit(clo, chi, r);
            const uint32_t bit = child_bit(n, c, nr.octinv);
            const bool got = (mask & bit) != 0;
            ++tested;
            exact_hits += exact;
            if (exact && !got) {
                ++misses;
                if (misses <= 5)
                    ADD_FAILURE() << "missed slot " << c << " iter " << iter << " k " << k << " dir " << r.dir[0]
                                  << "," << r.dir[1] << "," << r.dir[2] << " tmin " << r.tmin << " tmax " << r.tmax;
            }
            if (!exact && got) ++extra;
            if (!exact && (ref_mask & bit) != 0) ++ref_extra;
        }
    }
    EXPECT_EQ(misses, 0u);
    if (which == Which::kFast) {
        std::printf("fast node test: %llu of %llu rays take it; on them the reference test has %llu extras\n",
                    (unsigned long long)fast_rays, (unsigned long long)rays, (unsigned long long)ref_extra);
        // random_dir_component spreads exponents widely: rays whose |rcp| exponents lie
        // more than kFastMaxRcpSpread apart (about 45 % here) take the reference test.
        EXPECT_GT(fast_rays, rays / 4);
    }
    std::printf("node test: %llu child tests, %llu exact hits, %llu misses, %llu conservative extras (%.3f%%)\n",
                (unsigned long long)tested, (unsigned long long)exact_hits, (unsigned long long)misses,
                (unsigned long long)extra, 100.0 * double(extra) / double(tested));
    EXPECT_GT(exact_hits, tested / 10);
}

TEST(NodeIntersect, NeverMissesExactlyHitChild) { check_never_misses(Which::kReference, 12345); }

TEST(NodeIntersect, FastTestNeverMissesExactlyHitChild) {
    check_never_misses(Which::kFast, 12345);
    check_never_misses(Which::kFast, 98765);
}

// The contract on compiled trees (the core's quantization, not random planes): the pairs
// the device self-check uses (fast_node_pairs.h), rays aimed into a child of each node.
TEST(NodeIntersect, FastTestNeverMissesOnCompiledNodes) {
    const std::vector<std::vector<TriangleRecord>> scenes = {random_soup(20000, 100.0f, 2.0f, 7),
                                                             cube_mesh(40, true).tris()};
    for (const std::vector<TriangleRecord>& tris : scenes) {
        const WideBvh w = build_wide(tris);
        const FastNodePairs fp = make_fast_node_pairs(w.nodes.data(), w.nodes.size(), 5, 60000);
        ASSERT_EQ(fp.nodes.size(), 60000u);
        uint64_t tested = 0, exact_hits = 0, misses = 0, extra = 0;
        for (size_t i = 0; i < fp.nodes.size(); ++i) {
            const CwbvhNode& n = fp.nodes[i];
            const uint32_t mask = intersect_node_fast(n, fp.node_rays[i], fp.rays[i].tmax, fp.scale.frame_word);
            for (int c = 0; c < 8; ++c) {
                if (n.meta[c] == 0) continue;
                float clo[3], chi[3];
                child_box(n, c, clo, chi);
                const bool exact = exact_box_hit(clo, chi, fp.rays[i]);
                const uint32_t bit = child_bit(n, c, fp.node_rays[i].octinv);
                const bool got = (mask & bit) != 0;
                ++tested;
                exact_hits += exact;
                if (exact && !got && ++misses <= 5) ADD_FAILURE() << "pair " << i << " slot " << c;
                extra += !exact && got;
            }
        }
        EXPECT_EQ(misses, 0u);
        EXPECT_GT(exact_hits, tested / 10);
        std::printf("compiled nodes: %llu child tests, %llu exact hits, %llu misses, %llu extras (%.3f%%)\n",
                    (unsigned long long)tested, (unsigned long long)exact_hits, (unsigned long long)misses,
                    (unsigned long long)extra, 100.0 * double(extra) / double(tested));
    }
}

// Far out of the usual range, still taken by the fast test: a node at scale 2^87 and
// directions near 2^115 (|rcp| near 2^-115). 2^(e - 103) f alone overflows there; the
// test must form J as 2^(e - 103) (f rcp) and still find the child the ray is aimed at.
TEST(NodeIntersect, FastTestHugeSceneAndHugeDirections) {
    Gen g(31);
    int taken = 0;
    for (int iter = 0; iter < 2000; ++iter) {
        const CwbvhNode n = random_node(g, 95);
        const int c = g.irange(0, 7);
        if (n.meta[c] == 0) continue;
        float lo[3], hi[3];
        child_box(n, c, lo, hi);
        Ray r;
        for (int a = 0; a < 3; ++a) {
            r.dir[a] = std::ldexp(g.uni(0.25f, 1.0f) * (g.coin() ? 1.0f : -1.0f), 115);
            const float target = lo[a] + (hi[a] - lo[a]) * 0.5f;
            r.org[a] = target - r.dir[a] * std::ldexp(1.0f, -110);  // about 2^5 grid-scale units away
        }
        r.tmin = 0.0f;
        r.tmax = INFINITY;
        if (!ray_is_traceable(r) || !exact_box_hit(lo, hi, r)) continue;
        NodeRay nr = make_node_ray(r);
        const NodeScale sc = node_scale(&n, 1);
        enable_fast_node_test(nr, sc, r.dir, 0.0f);
        if (!nr.uses_fast_test()) continue;
        ++taken;
        const uint32_t mask = intersect_node_fast(n, nr, r.tmax, sc.frame_word);
        ASSERT_NE(mask & child_bit(n, c, nr.octinv), 0u) << "iter " << iter;
    }
    EXPECT_GT(taken, 500);
}

TEST(NodeIntersect, NodeScaleBoundsEveryNodeAndRefusesWhatTheFastTestCannotExpress) {
    Gen g(4242);
    std::vector<CwbvhNode> nodes;
    for (int i = 0; i < 500; ++i) nodes.push_back(random_node(g, g.irange(-30, 30)));
    const NodeScale sc = node_scale(nodes.data(), nodes.size());
    ASSERT_EQ(sc.usable, 1u);
    uint32_t emin = 255, emax = 0;
    for (const CwbvhNode& n : nodes)
        for (int a = 0; a < 3; ++a) {
            EXPECT_GE(double(sc.plane_max), std::fabs(double(n.p[a])) + 255.0 * double(exponent_scale(n.e[a])));
            EXPECT_GE(sc.scale_max, exponent_scale(n.e[a]));
            emin = std::min<uint32_t>(emin, n.e[a]);
            emax = std::max<uint32_t>(emax, n.e[a]);
        }
    EXPECT_EQ(sc.e_max, emax);
    EXPECT_EQ(sc.e_floor, emax > 101 ? emax - 100 : 1u);
    EXPECT_EQ(sc.frame_word, sc.e_floor << 8);    // low byte zero: the plane permutes' zero byte
    // Exponent 0 (planes all at p), exponents beyond kFastMaxExponent, a NaN or huge
    // origin, no nodes: no fast test.
    auto refused = [&](auto edit) {
        std::vector<CwbvhNode> bad = nodes;
        edit(bad[123]);
        return node_scale(bad.data(), bad.size()).usable == 0;
    };
    EXPECT_TRUE(refused([](CwbvhNode& n) { n.e[1] = 0; }));
    EXPECT_TRUE(refused([](CwbvhNode& n) { n.e[2] = uint8_t(kFastMaxExponent + 1); }));
    EXPECT_FALSE(refused([](CwbvhNode& n) { n.e[2] = uint8_t(kFastMaxExponent); }));
    EXPECT_TRUE(refused([](CwbvhNode& n) { n.p[0] = std::nanf(""); }));
    EXPECT_TRUE(refused([](CwbvhNode& n) { n.p[0] = 3e38f; }));
    EXPECT_EQ(node_scale(nodes.data(), 0).usable, 0u);
    // A ray set-up against these bounds: accepted for an ordinary ray, refused for
    // tmin < 0, a zero or tiny direction component, and an origin far enough out.
    const Ray ok{{1, 2, 3}, 0.0f, {0.3f, -0.5f, 0.8f}, INFINITY};
    auto fast = [&](Ray r, float tmin) {
        NodeRay nr = make_node_ray(r);
        enable_fast_node_test(nr, sc, r.dir, tmin);
        return nr.uses_fast_test();
    };
    EXPECT_TRUE(fast(ok, 0.0f));
    EXPECT_TRUE(fast(ok, 2.5f));
    EXPECT_FALSE(fast(ok, -1.0f));
    EXPECT_FALSE(fast(ok, -0.0f));  // the lane makes -0 +0 first
    Ray r = ok;
    r.dir[1] = 0.0f;
    EXPECT_FALSE(fast(r, 0.0f));
    r.dir[1] = 1e-30f;
    EXPECT_FALSE(fast(r, 0.0f));
    r = ok;
    r.org[0] = 1e37f;
    EXPECT_FALSE(fast(r, 0.0f));
    // The node frame's factors f = 2^(116 - e_max - r) and 2^-20 f must be normal floats
    // for every node: the ray's r = floor(log2 max|rcp|) is accepted up to 222 - e_max.
    // (Every component scaled alike: the exponents' spread stays 0.)
    const int r_last = 222 - int(sc.e_max);
    for (int a = 0; a < 3; ++a) r.dir[a] = std::ldexp(1.0f, -r_last);  // rcp = 2^r_last
    r.org[0] = ok.org[0];
    EXPECT_TRUE(fast(r, 0.0f)) << r_last;
    for (int a = 0; a < 3; ++a) r.dir[a] = std::ldexp(1.0f, -r_last - 1);
    EXPECT_FALSE(fast(r, 0.0f)) << r_last + 1;
    // The |rcp| exponents' spread (kFastMaxRcpSpread, a culling limit): rcp_x, rcp_y have
    // exponent 1 (3.33, -2); rcp_z = 5000 has 12 (spread 11: accepted), 9000 has 13 (12:
    // refused, the reference test).
    static_assert(kFastMaxRcpSpread == 11);
    r = ok;
    r.dir[2] = 1.0f / 5000.0f;
    EXPECT_TRUE(fast(r, 0.0f));
    r.dir[2] = -1.0f / 5000.0f;
    EXPECT_TRUE(fast(r, 0.0f));
    r.dir[2] = 1.0f / 9000.0f;
    EXPECT_FALSE(fast(r, 0.0f));
    r.dir[2] = 1.0f / 3.0f;
    r.dir[0] = 1.0f / 9000.0f;
    EXPECT_FALSE(fast(r, 0.0f));
}

TEST(NodeIntersect, ScalarAndSimdAgreeBitForBit) {
    // intersect_node_scalar (device, non-SSE hosts) and the host SIMD path must give
    // the same mask for every node, including malformed metas and extreme exponents,
    // so the CPU reference and the GPU kernels visit the same children.
    Gen g(777);
    uint64_t tested = 0, differ = 0;
    for (int iter = 0; iter < 200000; ++iter) {
        const int k = g.coin(0.2) ? g.irange(-120, 120) : g.irange(-4, 4);
        CwbvhNode n = random_node(g, k);
        if (g.coin(0.1)) {
            for (int s = 0; s < 8; ++s) n.meta[s] = uint8_t(g.irange(0, 255));  // any bytes
        }
        if (g.coin(0.05)) n.e[g.irange(0, 2)] = uint8_t(g.irange(0, 255));
        Ray r;
        for (int a = 0; a < 3; ++a) {
            r.dir[a] = random_dir_component(g, true);
            if (g.coin(0.05)) r.dir[a] = std::ldexp(g.uni(-1, 1), g.irange(-140, 127));
            r.org[a] = n.p[a] + std::ldexp(g.uni(-8, 8), k);
        }
        r.tmin = g.coin(0.8) ? 0.0f : -INFINITY;
        r.tmax = g.coin(0.5) ? INFINITY : std::ldexp(g.uni(0, 8), k);
        if (!ray_is_traceable(r)) continue;
        const NodeRay nr = make_node_ray(r);
        const uint32_t scalar = intersect_node_scalar(n, nr, r.tmin, r.tmax);
        ++tested;
        differ += scalar != intersect_node(n, nr, r.tmin, r.tmax);
#if CWBVH_NODE_SSE
        differ += scalar != intersect_node_sse(n, nr, r.tmin, r.tmax);
#endif
    }
    EXPECT_EQ(differ, 0u);
    EXPECT_GT(tested, 100000u);
}

// The kernels hand the node test NodeWords (twenty words from five 16-byte loads), the
// host the CwbvhNode: same group fields, same hit masks from both node tests.
TEST(NodeIntersect, NodeWordsAreTheNodeAndGiveTheSameMasks) {
    Gen g(777);
    int fast = 0;
    for (int iter = 0; iter < 20000; ++iter) {
        const CwbvhNode n = random_node(g, g.irange(-8, 8));
        CwbvhNode copy;
        memcpy(&copy, &n, sizeof n);
        const NodeWords w = load_node_words(&copy);
        ASSERT_EQ(node_child_base(w), n.child_base);
        ASSERT_EQ(node_tri_base(w), n.tri_base);
        ASSERT_EQ(node_imask(w), uint32_t(n.imask));
        ASSERT_EQ(memcmp(&w, &n, sizeof n), 0);
        const CwbvhNode back = node_from_words(w);
        ASSERT_EQ(memcmp(&back, &n, sizeof n), 0);
        Ray r;
        for (int a = 0; a < 3; ++a) {
            r.dir[a] = random_dir_component(g, true);
            r.org[a] = n.p[a] + std::ldexp(g.uni(-300.0f, 300.0f), n.e[a] - 127);
        }
        if (r.dir[0] == 0 && r.dir[1] == 0 && r.dir[2] == 0) r.dir[0] = 1.0f;
        r.tmin = 0.0f;
        r.tmax = g.coin() ? INFINITY : std::ldexp(g.uni(0.0f, 600.0f), n.e[0] - 127);
        if (!ray_is_traceable(r)) continue;
        NodeRay nr = make_node_ray(r);
        const NodeScale sc = node_scale(&n, 1);
        enable_fast_node_test(nr, sc, r.dir, 0.0f);
        fast += int(nr.uses_fast_test());
        ASSERT_EQ(intersect_node_dispatch(w, nr, r.tmin, r.tmax, sc.frame_word),
                  intersect_node_dispatch(n, nr, r.tmin, r.tmax, sc.frame_word))
            << "iter " << iter << " fast " << nr.uses_fast_test();
        const NodeRay ref = make_node_ray(r);  // the reference test (no kFastBit)
        ASSERT_EQ(intersect_node_dispatch(w, ref, r.tmin, r.tmax, sc.frame_word), intersect_node(n, ref, r.tmin, r.tmax));
    }
    EXPECT_GT(fast, 1000);  // the words path of the fast test ran
}

TEST(NodeIntersect, MetaDecodeSetsPaperBits) {
    // A node whose 8 children all contain the origin: every bit must come out.
    CwbvhNode n{};
    for (int a = 0; a < 3; ++a) n.e[a] = 127;
    n.meta[0] = make_meta_leaf(3, 0);
    n.meta[1] = make_meta_leaf(2, 3);
    n.meta[2] = make_meta_leaf(1, 23);
    for (int s = 3; s < 8; ++s) {
        n.meta[s] = make_meta_internal(s);
        n.imask |= uint8_t(1u << s);
    }
    for (int s = 0; s < 8; ++s)
        for (int a = 0; a < 3; ++a) n.q_hi[a][s] = 10;
    for (int oct = 0; oct < 8; ++oct) {
        const float o[3] = {1, 1, 1};
        const float d[3] = {(oct & 4) ? -1.f : 1.f, (oct & 2) ? -1.f : 1.f, (oct & 1) ? -1.f : 1.f};
        Ray r{{o[0], o[1], o[2]}, 0.0f, {d[0], d[1], d[2]}, INFINITY};
        const NodeRay nr = make_node_ray(r);
        EXPECT_EQ(nr.octinv, 7u - uint32_t(oct));
        uint32_t expect = 0x1Fu | (1u << 23);
        for (int s = 3; s < 8; ++s) expect |= 1u << (24 + (s ^ (7 - oct)));
        EXPECT_EQ(intersect_node(n, nr, r.tmin, r.tmax), expect) << "octant " << oct;
    }
}

// segment_reach rounds outwards: the reach e lies at or beyond the exact o + d T (T =
// min(tmax, 2^128)) in the direction of d, and within a few float steps of it. Inputs where
// o + d T is exact in long double (o = 0, or exponents of o and d T within 16 of each other;
// d T is exact in double), so the comparison is exact. A reach rounded to nearest fails it.
TEST(NodeIntersect, SegmentReachRoundsOutwards) {
    std::mt19937_64 rng(2027);
    std::uniform_real_distribution<float> m(0.5f, 1.0f);
    uint64_t checked = 0, inward = 0, loose = 0;
    for (int i = 0; i < 200000; ++i) {
        const float sd = (rng() & 1) ? 1.0f : -1.0f, so = (rng() & 1) ? 1.0f : -1.0f;
        const bool huge = rng() % 4 == 0;
        const float d = sd * std::ldexp(m(rng), huge ? 64 + int(rng() % 63) : -149 + int(rng() % 84));
        const float tmax = rng() % 3 == 0 ? INFINITY : std::ldexp(m(rng), int(rng() % 260) - 130);
        if (d == 0.0f || !reach_needs_double(d)) continue;
        const long double T = tmax > FLT_MAX ? std::ldexp(1.0L, 128) : (long double)tmax;
        const long double p = (long double)d * T;  // exact
        if (!std::isfinite((double)p) || p == 0) continue;
        int ep = 0;
        std::frexp((double)p, &ep);
        const float o = rng() % 4 == 0 ? 0.0f : so * std::ldexp(m(rng), ep + int(rng() % 33) - 16);
        if (!std::isfinite(o)) continue;  // not a traceable ray
        const long double exact = (long double)o + p;  // exact: the bits span at most 16 + 48 = 64
        const float e = segment_reach(o, d, tmax);
        ++checked;
        const bool out = d > 0 ? (long double)e >= exact : (long double)e <= exact;
        inward += !out;
        if (std::isfinite(e)) {
            const float back = d > 0 ? std::nextafter(std::nextafter(e, -INFINITY), -INFINITY)
                                     : std::nextafter(std::nextafter(e, INFINITY), INFINITY);
            loose += d > 0 ? (long double)back > exact : (long double)back < exact;  // more than 2 steps out
        }
    }
    EXPECT_GT(checked, 100000u);
    EXPECT_EQ(inward, 0u);
    EXPECT_EQ(loose, 0u);
}

TEST(NodeIntersect, FlatAndZeroDirection) {
    // A flat child (qlo == qhi on z) hit by a ray in its plane (dz = +0 and -0), and
    // a ray crossing it (tnear == tfar): both must hit (<=, not <).
    CwbvhNode n{};
    for (int a = 0; a < 3; ++a) n.e[a] = 127;
    n.meta[0] = make_meta_leaf(1, 0);
    for (int a = 0; a < 3; ++a) {
        n.q_lo[a][0] = 2;
        n.q_hi[a][0] = 6;
    }
    n.q_lo[2][0] = n.q_hi[2][0] = 4;
    for (float dz : {0.0f, -0.0f}) {
        Ray r{{0, 3, 4}, 0.0f, {1, 0, dz}, INFINITY};
        EXPECT_EQ(intersect_node(n, make_node_ray(r), r.tmin, r.tmax) & 1u, 1u);
        r.org[2] = std::nextafter(4.0f, 5.0f);
        EXPECT_EQ(intersect_node(n, make_node_ray(r), r.tmin, r.tmax) & 1u, 0u);  // exact: outside
    }
    Ray r{{3, 3, 0}, 0.0f, {0, 0, 1}, INFINITY};
    EXPECT_EQ(intersect_node(n, make_node_ray(r), r.tmin, r.tmax) & 1u, 1u);
    r.tmin = r.tmax = 4.0f;  // point query exactly on the flat box
    EXPECT_EQ(intersect_node(n, make_node_ray(r), r.tmin, r.tmax) & 1u, 1u);
}

}  // namespace
}  // namespace cwbvh::test
