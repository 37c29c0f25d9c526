// Two-level traversal (traverse_two_level.h, issue 19) against its flattened twin
// (the same placements' triangles moved to world space and compiled as one scene),
// and the adversarial placements: mirrored instances (watertightness and hit
// orientation), huge translations, near-singular transforms, one mesh placed 10^5
// times, degenerate instance records, any-hit.
#include <gtest/gtest.h>

#include <cstring>

#include <array>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/traverse_two_level.h"
#include "two_level_scene.h"

namespace cwbvh::test {
namespace {

using M34 = double[3][4];

constexpr double kU = 5.9604644775390625e-08;  // 2^-24

double len(const float* d) { return std::sqrt(double(d[0]) * d[0] + double(d[1]) * d[1] + double(d[2]) * d[2]); }

/// Rotation (unit quaternion from three uniforms, Shoemake) times diag(s), then
/// translation t: x_world = R S x + t.
void make_transform(std::mt19937& rng, const double (&s)[3], const double (&t)[3], M34& m) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double u1 = u(rng), u2 = 2 * M_PI * u(rng), u3 = 2 * M_PI * u(rng);
    const double a = std::sqrt(1 - u1), b = std::sqrt(u1);
    const double x = a * std::sin(u2), y = a * std::cos(u2), z = b * std::sin(u3), w = b * std::cos(u3);
    const double r[3][3] = {{1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)},
                            {2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)},
                            {2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)}};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) m[i][j] = r[i][j] * s[j];
        m[i][3] = t[i];
    }
}

/// Flips triangles so that every normal points away from `centre` (cube_mesh's
/// faces are wound alike on opposite sides; a facing test needs one orientation).
Mesh orient_outward(Mesh m, const double (&centre)[3]) {
    for (size_t i = 0; i + 2 < m.idx.size(); i += 3) {
        const float* a = &m.v[3 * m.idx[i]];
        const float* b = &m.v[3 * m.idx[i + 1]];
        const float* c = &m.v[3 * m.idx[i + 2]];
        double e1[3], e2[3], g[3];
        for (int k = 0; k < 3; ++k) {
            e1[k] = double(b[k]) - a[k];
            e2[k] = double(c[k]) - a[k];
            g[k] = (double(a[k]) + b[k] + c[k]) / 3 - centre[k];
        }
        const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                             e1[0] * e2[1] - e1[1] * e2[0]};
        if (n[0] * g[0] + n[1] * g[1] + n[2] * g[2] < 0) std::swap(m.idx[i + 1], m.idx[i + 2]);
    }
    return m;
}

double det3(const float (&m)[3][4]) {
    return double(m[0][0]) * (double(m[1][1]) * m[2][2] - double(m[1][2]) * m[2][1]) -
           double(m[0][1]) * (double(m[1][0]) * m[2][2] - double(m[1][2]) * m[2][0]) +
           double(m[0][2]) * (double(m[1][0]) * m[2][1] - double(m[1][1]) * m[2][0]);
}

/// Exact-ish double ray/triangle (Moller-Trumbore in double, barycentric slack
/// `eps`): the t of the hit or NaN.
double ray_tri_double(const double* o, const double* d, const double (&v)[3][3], double eps = 0.0) {
    double e1[3], e2[3], p[3], tv[3], q[3];
    for (int a = 0; a < 3; ++a) {
        e1[a] = v[1][a] - v[0][a];
        e2[a] = v[2][a] - v[0][a];
        tv[a] = o[a] - v[0][a];
    }
    p[0] = d[1] * e2[2] - d[2] * e2[1];
    p[1] = d[2] * e2[0] - d[0] * e2[2];
    p[2] = d[0] * e2[1] - d[1] * e2[0];
    const double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    if (det == 0.0) return NAN;
    const double u = (tv[0] * p[0] + tv[1] * p[1] + tv[2] * p[2]) / det;
    q[0] = tv[1] * e1[2] - tv[2] * e1[1];
    q[1] = tv[2] * e1[0] - tv[0] * e1[2];
    q[2] = tv[0] * e1[1] - tv[1] * e1[0];
    const double w = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
    if (u < -eps || w < -eps || u + w > 1 + eps) return NAN;
    return (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) / det;
}

/// Sign of n . d for the world-space triangle v (winding as stored).
int facing(const double (&v)[3][3], const float* dir) {
    double e1[3], e2[3];
    for (int a = 0; a < 3; ++a) {
        e1[a] = v[1][a] - v[0][a];
        e2[a] = v[2][a] - v[0][a];
    }
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double s = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2];
    return s > 0 ? 1 : (s < 0 ? -1 : 0);
}

/// |cos| of the angle between the triangle's normal and dir.
double cosine(const double (&v)[3][3], const float* dir) {
    double e1[3], e2[3];
    for (int a = 0; a < 3; ++a) {
        e1[a] = v[1][a] - v[0][a];
        e2[a] = v[2][a] - v[0][a];
    }
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    const double nl = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    return std::fabs(n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2]) / (nl * len(dir));
}

struct TwoLevelHits {
    std::vector<Hit> hits;
    std::vector<uint32_t> inst;
    CpuTraceStats stats;
};

/// scale: the fast node test's constants (what DeviceScene::upload gives the kernel);
/// NodeScale{} runs the CPU reference's node test.
TwoLevelHits trace_two_level(const TwoLevelBuild& b, const std::vector<Ray>& rays, HitMode mode = HitMode::kClosest,
                             const NodeScale& scale = NodeScale{}) {
    TwoLevelHits r;
    r.hits.resize(rays.size());
    r.inst.resize(rays.size());
    CpuTraceOptions o;
    o.mode = mode;
    o.threads = 1;
    std::vector<TraceStatus> st(rays.size());
    o.statuses = st.data();
    TwoLevelScene view = b.view();
    view.node_scale = scale;
    r.stats = trace_two_level_cpu(view, rays.data(), r.hits.data(), r.inst.data(), rays.size(), o);
    for (size_t i = 0; i < rays.size(); ++i) EXPECT_TRUE(st[i] == TraceStatus::kOk) << "ray " << i;
    return r;
}

std::vector<Hit> trace_flat(const FlatBuild& f, const std::vector<Ray>& rays, HitMode mode = HitMode::kClosest) {
    std::vector<Hit> hits(rays.size());
    CpuTraceOptions o;
    o.mode = mode;
    o.threads = 1;
    trace_cwbvh_cpu(f.wide.nodes.data(), f.wide.nodes.size(), f.wide.tris.data(), f.wide.tris.size(), rays.data(),
                    hits.data(), rays.size(), o);
    return hits;
}

/// Rays between random points of the box [lo, hi] (widened by 10 %).
std::vector<Ray> random_rays(const float* lo, const float* hi, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::vector<Ray> rays;
    for (size_t i = 0; i < n; ++i) {
        float a[3], b[3];
        for (int k = 0; k < 3; ++k) {
            const double ext = double(hi[k]) - lo[k];
            std::uniform_real_distribution<double> u(lo[k] - 0.1 * ext, hi[k] + 0.1 * ext);
            a[k] = float(u(rng));
            b[k] = float(u(rng));
        }
        float d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        if (d[0] == 0 && d[1] == 0 && d[2] == 0) d[0] = 1;
        rays.push_back(make_ray(a, d));
    }
    return rays;
}

void world_box(const TwoLevelBuild& b, float (&lo)[3], float (&hi)[3]) {
    for (int a = 0; a < 3; ++a) {
        lo[a] = INFINITY;
        hi[a] = -INFINITY;
    }
    for (const InstanceRecord& r : b.instances)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], r.world_lo[a]);
            hi[a] = std::max(hi[a], r.world_hi[a]);
        }
}

struct Agreement {
    size_t rays = 0, hits = 0, hit_mismatch = 0, edge_ambiguous = 0, t_mismatch = 0, t_rounding = 0,
           prim_mismatch = 0, ties = 0, facing_mismatch = 0;
};



/// The criterion: hit/miss equal; t within 1e-5 relative; the same source
/// primitive (flattened prim -> (instance, prim)) or an equal-t tie: the two-level
/// hit's triangle, moved to world space in double, is hit by the ray (barycentric
/// slack 1e-6) at a t within 1e-5 of the flattened t. Also the world-space facing
/// of the hit triangle (winding as stored, mirrored or not) agrees.
Agreement compare(const TwoLevelBuild& b, const FlatBuild& f, const std::vector<Ray>& rays, const TwoLevelHits& two,
                  const std::vector<Hit>& flat) {
    Agreement a;
    float lo[3], hi[3];
    world_box(b, lo, hi);
    double extent = 0;
    for (int k = 0; k < 3; ++k) extent = std::max({extent, std::fabs(double(lo[k])), std::fabs(double(hi[k]))});
    for (size_t i = 0; i < rays.size(); ++i) {
        ++a.rays;
        const Hit& h = two.hits[i];
        const Hit& g = flat[i];
        const bool hit = h.prim != kMissPrim;
        EXPECT_EQ(hit, two.inst[i] != kInvalidIndex);
        if (hit != (g.prim != kMissPrim)) {
            // Only a ray through the exact (double) world triangle of the hit, with a
            // margin of 1e-4 in barycentrics from its edges, makes the other side's
            // miss wrong; closer to an edge the flattened file's rounded vertices
            // and the two-level ray's rounding may each decide either way.
            double v[3][3], o[3], d[3];
            if (hit) b.world_triangle(two.inst[i], h.prim, v);
            else b.world_triangle(f.source[g.prim].first, f.source[g.prim].second, v);
            for (int k = 0; k < 3; ++k) {
                o[k] = rays[i].org[k];
                d[k] = rays[i].dir[k];
            }
            const double t = ray_tri_double(o, d, v, -1e-4);
            if (t == t) ++a.hit_mismatch;
            else ++a.edge_ambiguous;
            continue;
        }
        if (!hit) continue;
        ++a.hits;
        const auto src = f.source[g.prim];
        double v[3][3], fv[3][3];
        b.world_triangle(two.inst[i], h.prim, v);
        b.world_triangle(src.first, src.second, fv);
        // t: 1e-5 relative; otherwise the gap, measured along the triangle's normal
        // (dt |d| cos), within 16 u of the scene's extent: both files round world
        // coordinates of that size (the flattened one its vertices, the two-level one
        // its object-space ray), which moves t by that over cos: a hit very near the
        // origin or at a grazing angle. Counted apart; any other gap fails.
        const double dt = std::fabs(double(h.t) - g.t);
        if (!(dt <= 1e-5 * std::fabs(double(g.t)))) {
            if (dt * len(rays[i].dir) * cosine(v, rays[i].dir) <= 16 * kU * extent) ++a.t_rounding;
            else ++a.t_mismatch;
        }
        if (src.first != two.inst[i] || src.second != h.prim) {
            double o[3], d[3];
            for (int k = 0; k < 3; ++k) {
                o[k] = rays[i].org[k];
                d[k] = rays[i].dir[k];
            }
            const double t = ray_tri_double(o, d, v, 1e-6);
            if (t == t && std::fabs(t - g.t) <= 1e-5 * std::fabs(double(g.t))) ++a.ties;
            else ++a.prim_mismatch;
        }
        if (facing(v, rays[i].dir) != facing(fv, rays[i].dir)) ++a.facing_mismatch;
    }
    return a;
}

void expect_agree(const Agreement& a, const char* what, size_t max_ties_per_mille = 20) {
    std::printf("%-28s rays %zu hits %zu  hit/miss %zu (edge %zu)  t %zu (rounding %zu)  prim %zu  ties %zu  "
                "facing %zu\n",
                what, a.rays, a.hits, a.hit_mismatch, a.edge_ambiguous, a.t_mismatch, a.t_rounding, a.prim_mismatch,
                a.ties, a.facing_mismatch);
    EXPECT_GT(a.hits, a.rays / 10) << what << ": too few hits for a meaningful comparison";
    EXPECT_EQ(a.hit_mismatch, 0u) << what;
    EXPECT_LE(a.edge_ambiguous * 10000, a.rays) << what;  // at most 1 in 10^4
    EXPECT_EQ(a.t_mismatch, 0u) << what;
    EXPECT_LE(a.t_rounding * 100, a.hits) << what;
    EXPECT_EQ(a.prim_mismatch, 0u) << what;
    EXPECT_EQ(a.facing_mismatch, 0u) << what;
    EXPECT_LE(a.ties * 1000, a.hits * max_ties_per_mille) << what;
}

std::vector<std::vector<TriangleRecord>> test_meshes() {
    Mesh sphere = cube_mesh(6, true);
    sphere.transform(1.0, -3.0);  // centred at the origin, radius 3
    sphere = orient_outward(sphere, {0, 0, 0});
    Mesh grid = grid_mesh(10);
    grid.transform(0.5, -2.5);
    std::vector<TriangleRecord> soup = random_soup(400, 6, 0.6f, 11);
    for (TriangleRecord& t : soup)
        for (float* v : {t.v0, t.v1, t.v2})
            for (int a = 0; a < 3; ++a) v[a] -= 3.0f;
    return {sphere.tris(), grid.tris(), soup};
}

/// `count` placements of the meshes in a cube of side `extent`, random rotations,
/// scales in [0.5, 2], every third one mirrored (one scale negative).
std::vector<Placement> random_placements(size_t count, uint32_t meshes, double extent, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> pos(0, extent), sc(0.5, 2.0);
    std::vector<Placement> p;
    for (size_t i = 0; i < count; ++i) {
        double s[3] = {sc(rng), sc(rng), sc(rng)};
        if (i % 3 == 1) s[i % 2] = -s[i % 2];
        const double t[3] = {pos(rng), pos(rng), pos(rng)};
        M34 m;
        make_transform(rng, s, t, m);
        p.push_back(make_placement(uint32_t(i % meshes), m));
    }
    return p;
}

TEST(TwoLevel, TestTlasContainsInstanceBoxes) {
    const TwoLevelBuild b = build_two_level(test_meshes(), random_placements(200, 3, 60, 1));
    ASSERT_EQ(b.instances.size(), 200u);
    // Every INST is in exactly one leaf, and every slot box on its path contains its
    // world box (checked from the root down with the normative decode).
    std::vector<int> seen(b.instances.size(), 0);
    struct Item {
        uint32_t node;
        compiler::Aabb box;
    };
    std::vector<Item> todo{{0, {}}};
    while (!todo.empty()) {
        const Item it = todo.back();
        todo.pop_back();
        const CwbvhNode& n = b.tlas[it.node];
        uint32_t child = n.child_base;
        for (int s = 0; s < 8; ++s) {
            const compiler::Aabb box = compiler::decode_child_box(n, s);
            if (meta_is_internal(n.meta[s])) {
                todo.push_back({child++, box});
            } else if (meta_is_leaf(n.meta[s])) {
                for (int k = 0; k < meta_leaf_count(n.meta[s]); ++k) {
                    const uint32_t ii = n.tri_base + meta_leaf_offset(n.meta[s]) + uint32_t(k);
                    ASSERT_LT(ii, b.instances.size());
                    ++seen[ii];
                    for (int a = 0; a < 3; ++a) {
                        EXPECT_LE(box.lo[a], b.instances[ii].world_lo[a]);
                        EXPECT_GE(box.hi[a], b.instances[ii].world_hi[a]);
                    }
                }
            }
        }
    }
    for (int c : seen) EXPECT_EQ(c, 1);
}

TEST(TwoLevel, MatchesFlattenedClosestAndAny) {
    const TwoLevelBuild b = build_two_level(test_meshes(), random_placements(60, 3, 40, 2));
    const FlatBuild f = flatten(b);
    float lo[3], hi[3];
    world_box(b, lo, hi);
    const std::vector<Ray> rays = random_rays(lo, hi, 20000, 3);
    const TwoLevelHits two = trace_two_level(b, rays);
    const std::vector<Hit> flat = trace_flat(f, rays);
    expect_agree(compare(b, f, rays, two, flat), "random placements, closest");

    // Any hit: a hit exactly when the closest query hits, and a real one: the same
    // triangle test on the instance's object-space ray accepts it at the same t.
    const TwoLevelHits any = trace_two_level(b, rays, HitMode::kAny);
    size_t hits = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        ASSERT_EQ(any.hits[i].prim != kMissPrim, two.hits[i].prim != kMissPrim) << "ray " << i;
        if (any.hits[i].prim == kMissPrim) continue;
        ++hits;
        EXPECT_GE(any.hits[i].t, two.hits[i].t);
        const InstanceRecord& inst = b.instances.at(any.inst[i]);
        const MeshRecord& m = b.meshes[inst.mesh];
        const Ray o = object_ray(inst, rays[i], rays[i].tmax);
        const TriangleIntersector<TriangleTest::kWatertight> test(o);
        bool found = false;
        for (uint32_t k = m.tri_first; k < m.tri_first + m.tri_count; ++k) {
            TriangleHit th;
            if (b.tris[k].prim == any.hits[i].prim && test(b.tris[k], o.tmin, o.tmax, th)) {
                found = th.t == any.hits[i].t && th.u == any.hits[i].u && th.v == any.hits[i].v;
                break;
            }
        }
        EXPECT_TRUE(found) << "ray " << i << ": any-hit answer is not a hit of its instance";
    }
    EXPECT_GT(hits, rays.size() / 10);
}

// The GPU kernel's node test (intersect_node_fast, enabled per world and per object-space
// ray by the scene constants over NODE and TLAS that DeviceScene::upload merges) gives
// the reference's hits, bit for bit, closest and any. The host runs the same arithmetic
// (intrinsics emulated exactly), so this is what the two-level kernel computes on sm_90.
TEST(TwoLevel, FastNodeTestGivesTheReferenceHits) {
    const TwoLevelBuild b = build_two_level(test_meshes(), random_placements(60, 3, 40, 2));
    float lo[3], hi[3];
    world_box(b, lo, hi);
    const std::vector<Ray> rays = random_rays(lo, hi, 20000, 5);
    const NodeScale scale = merge_node_scale(node_scale(b.nodes.data(), b.nodes.size()),
                                             node_scale(b.tlas.data(), b.tlas.size()));
    ASSERT_EQ(scale.usable, 1u);
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        const TwoLevelHits ref = trace_two_level(b, rays, mode);
        const TwoLevelHits fast = trace_two_level(b, rays, mode, scale);
        size_t hits = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            hits += ref.hits[i].prim != kMissPrim;
            if (mode == HitMode::kClosest) {
                ASSERT_EQ(std::memcmp(&ref.hits[i], &fast.hits[i], sizeof(Hit)), 0) << "ray " << i;
                ASSERT_EQ(ref.inst[i], fast.inst[i]) << "ray " << i;
            } else {
                ASSERT_EQ(ref.hits[i].prim != kMissPrim, fast.hits[i].prim != kMissPrim) << "ray " << i;
            }
        }
        EXPECT_GT(hits, rays.size() / 10);
    }
    // And the fast test did run: the scene constants admit (nearly) every world ray.
    size_t enabled = 0;
    for (const Ray& r : rays) {
        NodeRay n = make_node_ray(r);
        enable_fast_node_test(n, scale, r.dir, r.tmin == 0.0f ? 0.0f : r.tmin);
        enabled += n.uses_fast_test() ? 1 : 0;
    }
    EXPECT_GT(enabled, rays.size() * 9 / 10);
    // A scene constant that cannot hold for TLAS (usable 0) turns the fast test off.
    NodeScale off = scale;
    off.usable = 0;
    EXPECT_EQ(merge_node_scale(scale, off).usable, 0u);
}

TEST(TwoLevel, CountersAndStatuses) {
    const TwoLevelBuild b = build_two_level(test_meshes(), random_placements(30, 3, 30, 4));
    LocalStack<kCpuStackSize> stack;
    Hit h;
    uint32_t inst = 0;
    // Untraceable ray: a miss without traversal.
    const float o[3] = {0, 0, 0}, zero[3] = {0, 0, 0};
    EXPECT_EQ((traverse_two_level<TriangleTest::kWatertight, HitMode::kClosest>(b.view(), make_ray(o, zero), h, inst,
                                                                               stack)),
              TraceStatus::kInvalidRay);
    EXPECT_EQ(h.prim, kMissPrim);
    EXPECT_EQ(inst, kInvalidIndex);
    // A corrupt instance (mesh index out of range) or top level (INST index out of
    // range) is reported, never read past.
    float lo[3], hi[3];
    world_box(b, lo, hi);
    const std::vector<Ray> rays = random_rays(lo, hi, 2000, 5);
    TwoLevelBuild bad = b;
    for (InstanceRecord& r : bad.instances) r.mesh = 7;
    TwoLevelBuild bad2 = b;
    bad2.instances.resize(1);
    size_t bad_mesh = 0, bad_inst = 0;
    for (const Ray& r : rays) {
        LocalStack<kCpuStackSize> s1, s2;
        bad_mesh += traverse_two_level<TriangleTest::kWatertight, HitMode::kClosest>(bad.view(), r, h, inst, s1) ==
                    TraceStatus::kBadIndex;
        bad_inst += traverse_two_level<TriangleTest::kWatertight, HitMode::kClosest>(bad2.view(), r, h, inst, s2) ==
                    TraceStatus::kBadIndex;
    }
    EXPECT_GT(bad_mesh, 0u);
    EXPECT_GT(bad_inst, 0u);
    // A stack too small for entering an instance reports an overflow.
    LocalStack<1> tiny;
    size_t overflow = 0;
    for (const Ray& r : rays)
        overflow += traverse_two_level<TriangleTest::kWatertight, HitMode::kClosest>(b.view(), r, h, inst, tiny) ==
                    TraceStatus::kStackOverflow;
    EXPECT_GT(overflow, 0u);
}

/// Rays from `centre` (world) to every vertex of every triangle of instance `ii`
/// and to its edge midpoints (world, rounded to float).
std::vector<Ray> rays_to_vertices(const TwoLevelBuild& b, uint32_t ii, const float* centre) {
    std::vector<Ray> rays;
    const MeshRecord& m = b.meshes[b.instances[ii].mesh];
    for (const TriangleRecord& t : b.mesh_tris[b.instances[ii].mesh]) {
        double v[3][3];
        b.world_triangle(ii, m.prim_first + t.prim, v);
        for (int k = 0; k < 3; ++k) {
            for (double w : {1.0, 0.5}) {
                float d[3];
                for (int a = 0; a < 3; ++a) d[a] = float(w * v[k][a] + (1 - w) * v[(k + 1) % 3][a] - centre[a]);
                // The surface is at t ~ 1 (a vertex) to 1/cos (an edge's midpoint):
                // tmax 1.25 keeps any-hit off the other instances.
                rays.push_back(make_ray(centre, d, 0.0f, 1.25f));
            }
        }
    }
    return rays;
}

/// Rays from the centre of a closed mesh through its vertices and edges: every one
/// hits (a crack would let one through), and every hit faces the same way (the
/// winding is consistent; a mirrored instance flips it in world space, as its
/// flattened twin does).
void expect_closed(const TwoLevelBuild& b, uint32_t ii, const float* centre, int want_facing, const char* what) {
    const std::vector<Ray> rays = rays_to_vertices(b, ii, centre);
    for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
        const TwoLevelHits h = trace_two_level(b, rays, mode);
        size_t miss = 0, wrong_facing = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            if (h.hits[i].prim == kMissPrim || h.inst[i] != ii) {
                ++miss;
                continue;
            }
            double v[3][3];
            b.world_triangle(h.inst[i], h.hits[i].prim, v);
            wrong_facing += facing(v, rays[i].dir) != want_facing;
        }
        EXPECT_EQ(miss, 0u) << what << (mode == HitMode::kAny ? " (any)" : " (closest)") << ": rays leaked";
        EXPECT_EQ(wrong_facing, 0u) << what;
    }
}

TEST(TwoLevel, MirroredClosedMeshIsWatertightAndFacesConsistently) {
    Mesh sphere = cube_mesh(8, true);
    sphere.transform(1.0, -4.0);
    sphere = orient_outward(sphere, {0, 0, 0});
    std::mt19937 rng(6);
    std::vector<Placement> p;
    const double plain[3] = {1, 1, 1}, mirror_x[3] = {-1, 1, 1}, mirror_all[3] = {-1.5, -0.75, -2};
    const double t0[3] = {0, 0, 0}, t1[3] = {20, 3, -7}, t2[3] = {-15, 11, 4};
    M34 m;
    make_transform(rng, plain, t0, m);
    p.push_back(make_placement(0, m));
    make_transform(rng, mirror_x, t1, m);
    p.push_back(make_placement(0, m));
    make_transform(rng, mirror_all, t2, m);
    p.push_back(make_placement(0, m));
    const TwoLevelBuild b = build_two_level({sphere.tris()}, p);
    // The facing of the unmirrored instance from inside; a negative determinant flips it.
    int base = 0;
    for (uint32_t ii = 0; ii < 3; ++ii)
        if (det3(b.instances[ii].object_to_world) > 0) {
            const float c[3] = {b.instances[ii].object_to_world[0][3], b.instances[ii].object_to_world[1][3],
                                b.instances[ii].object_to_world[2][3]};
            const std::vector<Ray> r = rays_to_vertices(b, ii, c);
            const TwoLevelHits h = trace_two_level(b, {r[0]});
            ASSERT_NE(h.hits[0].prim, kMissPrim);
            double v[3][3];
            b.world_triangle(h.inst[0], h.hits[0].prim, v);
            base = facing(v, r[0].dir);
        }
    ASSERT_NE(base, 0);
    for (uint32_t ii = 0; ii < 3; ++ii) {
        const InstanceRecord& r = b.instances[ii];
        const float c[3] = {r.object_to_world[0][3], r.object_to_world[1][3], r.object_to_world[2][3]};
        const int want = det3(r.object_to_world) > 0 ? base : -base;
        expect_closed(b, ii, c, want, det3(r.object_to_world) > 0 ? "plain instance" : "mirrored instance");
    }
    // And the flattened twin agrees ray for ray (facing included).
    const FlatBuild f = flatten(b);
    float lo[3], hi[3];
    world_box(b, lo, hi);
    const std::vector<Ray> rays = random_rays(lo, hi, 5000, 7);
    expect_agree(compare(b, f, rays, trace_two_level(b, rays), trace_flat(f, rays)), "mirrored spheres");
}

TEST(TwoLevel, MirroredGridHasNoCracks) {
    // A flat grid instanced mirrored: rays through every interior vertex and edge
    // midpoint (world space) hit. The grid lies in its object z = 0 plane.
    Mesh grid = grid_mesh(12, false);
    grid.transform(1.0, -6.0);
    for (size_t i = 2; i < grid.v.size(); i += 3) grid.v[i] = 0.0f;
    std::mt19937 rng(8);
    std::vector<Placement> p;
    const double scales[4][3] = {{1, 1, 1}, {-1, 1, 1}, {1, -3, 1}, {-0.5, -2, -1}};
    for (int k = 0; k < 4; ++k) {
        const double t[3] = {100.0 * k, 50.0 * k, -30.0 * k};  // apart: no instance shadows another
        M34 m;
        make_transform(rng, scales[k], t, m);
        p.push_back(make_placement(0, m));
    }
    const TwoLevelBuild b = build_two_level({grid.tris()}, p);
    for (uint32_t ii = 0; ii < 4; ++ii) {
        const InstanceRecord& r = b.instances[ii];
        // Origin: 5 units off the plane along the world normal of the grid, tilted.
        const float local_o[3] = {0.37f, -0.21f, 5.0f};
        double o[3];
        apply_affine(r.object_to_world, local_o, o);
        const float of[3] = {float(o[0]), float(o[1]), float(o[2])};
        std::vector<Ray> rays;
        for (int j = 1; j < 24; ++j)
            for (int i = 1; i < 24; ++i) {
                const float target[3] = {-6.0f + 0.5f * float(i), -6.0f + 0.5f * float(j), 0.0f};
                double w[3];
                apply_affine(r.object_to_world, target, w);
                const float d[3] = {float(w[0] - of[0]), float(w[1] - of[1]), float(w[2] - of[2])};
                rays.push_back(make_ray(of, d));
            }
        for (HitMode mode : {HitMode::kClosest, HitMode::kAny}) {
            const TwoLevelHits h = trace_two_level(b, rays, mode);
            size_t miss = 0;
            for (size_t i = 0; i < rays.size(); ++i) miss += h.hits[i].prim == kMissPrim || h.inst[i] != ii;
            ASSERT_EQ(rays.size(), 23u * 23u);
            EXPECT_EQ(miss, 0u) << "instance " << ii << " det " << det3(r.object_to_world);
        }
    }
}

/// Closest t of the world ray (double) against instance ii's triangles (double).
double exact_t(const TwoLevelBuild& b, uint32_t ii, const Ray& r) {
    const MeshRecord& m = b.meshes[b.instances[ii].mesh];
    double best = INFINITY;
    const double o[3] = {r.org[0], r.org[1], r.org[2]}, d[3] = {r.dir[0], r.dir[1], r.dir[2]};
    for (const TriangleRecord& t : b.mesh_tris[b.instances[ii].mesh]) {
        double v[3][3];
        b.world_triangle(ii, m.prim_first + t.prim, v);
        const double th = ray_tri_double(o, d, v, 1e-9);
        if (th == th && th >= 0 && th < best) best = th;
    }
    return best;
}

/// Rays from random points near instance ii's centre (within `reach`, object
/// units) in random directions: every one must hit instance ii (closed mesh), at a
/// t within the rounding bound of moving the ray to object space: origin and
/// direction each err by a few u of |W2O| times their size, which the instance
/// maps back with |O2W|, so the hit point errs by about
///   16 u cond (|o| + t |d|)    (cond = |O2W| |W2O|, |o|: the world origin's size),
/// plus 1e-6 t |d| for the triangle test itself.
void expect_inside_rays_hit(const TwoLevelBuild& b, uint32_t ii, double reach, double cond, const char* what) {
    std::mt19937 rng(9);
    std::normal_distribution<double> g(0, 1);
    std::uniform_real_distribution<double> u(-reach, reach);
    const InstanceRecord& r = b.instances[ii];
    std::vector<Ray> rays;
    for (int i = 0; i < 2000; ++i) {
        float o[3], d[3];
        const float local[3] = {float(u(rng)), float(u(rng)), float(u(rng))};
        double w[3];
        apply_affine(r.object_to_world, local, w);
        for (int a = 0; a < 3; ++a) {
            o[a] = float(w[a]);
            d[a] = float(g(rng));
        }
        rays.push_back(make_ray(o, d));
    }
    const TwoLevelHits h = trace_two_level(b, rays);
    size_t miss = 0, off = 0;
    double worst = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        if (h.hits[i].prim == kMissPrim || h.inst[i] != ii) {
            ++miss;
            continue;
        }
        const double t = exact_t(b, ii, rays[i]);
        const double dl = len(rays[i].dir);
        const double omax = std::max({std::fabs(double(rays[i].org[0])), std::fabs(double(rays[i].org[1])),
                                      std::fabs(double(rays[i].org[2]))});
        const double bound = 16 * kU * cond * (omax + t * dl) + 1e-6 * t * dl;
        const double err = std::fabs(double(h.hits[i].t) - t) * dl;
        worst = std::max(worst, err / bound);
        off += !(err <= bound);
    }
    std::printf("%-28s rays %zu  leaked %zu  worst t error %.3g of its bound\n", what, rays.size(), miss, worst);
    EXPECT_EQ(miss, 0u) << what;
    EXPECT_EQ(off, 0u) << what;
}

TEST(TwoLevel, HugeTranslations) {
    // A closed sphere of radius 400 placed ~4e6 from the origin (float spacing 0.25
    // there), next to one at the origin. The object-space ray is computed from the
    // world ray exactly as stored (fma chain): its origin errs by ~u |translation|,
    // so t errs by about u |T| / |d| (rel. ~2e-8 * 4e6 / 400 = 2e-4 at worst near
    // the centre); what must hold is no leak and that bound.
    Mesh sphere = cube_mesh(10, true);
    sphere.transform(80.0, -400.0);
    std::mt19937 rng(10);
    std::vector<Placement> p;
    const double s[3] = {1, 1, 1}, sm[3] = {1, -1, 1};
    const double far[3] = {4.0e6, -2.5e6, 3.0e6}, far2[3] = {-3.1e6, 3.9e6, -1.0e6}, near[3] = {0, 0, 0};
    M34 m;
    make_transform(rng, s, far, m);
    p.push_back(make_placement(0, m));
    make_transform(rng, sm, far2, m);
    p.push_back(make_placement(0, m));
    make_transform(rng, s, near, m);
    p.push_back(make_placement(0, m));
    const TwoLevelBuild b = build_two_level({sphere.tris()}, p);
    for (uint32_t ii = 0; ii < 3; ++ii)
        expect_inside_rays_hit(b, ii, 150, 1.0,
                               b.instances[ii].object_to_world[0][3] != 0 ? "huge translation" : "at the origin");
}

TEST(TwoLevel, NearSingularTransforms) {
    // Condition numbers up to ~2^19 (the spec's bound is 2^20): a closed mesh stays
    // closed (no leak) and t is within the conditioning bound (expect_inside_rays_hit).
    Mesh sphere = cube_mesh(8, true);
    sphere.transform(1.0, -4.0);
    std::mt19937 rng(11);
    std::vector<Placement> p;
    const double scales[3][3] = {{700, 1, 1.0 / 700}, {-1000, 0.5, 1.0 / 512}, {1, 1e-3, 1e-3}};
    const double conds[3] = {700 * 700, 1000 * 512, 1000};
    for (int k = 0; k < 3; ++k) {
        const double t[3] = {50.0 * k, -30.0 * k, 10.0 * k};
        M34 m;
        make_transform(rng, scales[k], t, m);
        p.push_back(make_placement(0, m));
    }
    const TwoLevelBuild b = build_two_level({sphere.tris()}, p);
    for (uint32_t ii = 0; ii < 3; ++ii) {
        const uint32_t k = b.inst_placement[ii];
        expect_inside_rays_hit(b, ii, 1.0, conds[k], "near-singular");
    }
}

TEST(TwoLevel, DegenerateInstanceRecordsAreSkipped) {
    // Records outside the spec's bounds (validation rejects them) must still not
    // crash or poison the others: an inverse whose object-space ray overflows to
    // inf, and a zero inverse (zero direction), are skipped; the rest still hit.
    const TwoLevelBuild good = build_two_level(test_meshes(), random_placements(30, 3, 30, 12));
    TwoLevelBuild b = good;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
            b.instances[0].world_to_object[r][c] = 3e38f;
            b.instances[1].world_to_object[r][c] = 0.0f;
        }
    float lo[3], hi[3];
    world_box(b, lo, hi);
    const std::vector<Ray> rays = random_rays(lo, hi, 5000, 13);
    const TwoLevelHits h = trace_two_level(b, rays);
    const TwoLevelHits g = trace_two_level(good, rays);
    size_t hits = 0, same = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
        EXPECT_TRUE(h.inst[i] != 0 && h.inst[i] != 1) << "ray " << i;
        if (h.hits[i].prim == kMissPrim) continue;
        ++hits;
        same += g.inst[i] == h.inst[i] && g.hits[i].t == h.hits[i].t;
    }
    EXPECT_GT(hits, rays.size() / 10);
    EXPECT_GT(same, hits / 2);
}

TEST(TwoLevel, OneMeshPlacedHundredThousandTimes) {
    // A small closed mesh placed 10^5 times on a jittered 50 x 50 x 40 lattice,
    // random rotations and scales (a third mirrored). TLAS depth ~7 levels.
    Mesh m = cube_mesh(1, true);
    m.transform(0.8, -0.4);
    m = orient_outward(m, {0, 0, 0});
    std::mt19937 rng(14);
    std::uniform_real_distribution<double> jit(-0.3, 0.3), sc(0.4, 0.9);
    std::vector<Placement> p;
    for (int z = 0; z < 40; ++z)
        for (int y = 0; y < 50; ++y)
            for (int x = 0; x < 50; ++x) {
                double s[3] = {sc(rng), sc(rng), sc(rng)};
                if (p.size() % 3 == 2) s[1] = -s[1];
                const double t[3] = {2.0 * x + jit(rng), 2.0 * y + jit(rng), 2.0 * z + jit(rng)};
                M34 a;
                make_transform(rng, s, t, a);
                p.push_back(make_placement(0, a));
            }
    ASSERT_EQ(p.size(), 100000u);
    const TwoLevelBuild b = build_two_level({m.tris()}, p);
    const FlatBuild f = flatten(b);
    float lo[3], hi[3];
    world_box(b, lo, hi);
    const std::vector<Ray> rays = random_rays(lo, hi, 4000, 15);
    const TwoLevelHits two = trace_two_level(b, rays);
    expect_agree(compare(b, f, rays, two, trace_flat(f, rays)), "one mesh x 100000");
    std::printf("  two-level nodes/ray %.1f  triangles/ray %.1f\n", double(two.stats.nodes_visited) / rays.size(),
                double(two.stats.triangles_tested) / rays.size());
}

TEST(TwoLevel, WorldTrianglesAndDiffuseBouncesMatchTheFlattenedScene) {
    // world_triangle (ray_gen.h: transform_point's fma order) against the double
    // transform, winding kept (a mirrored instance's normal flips with it); and the
    // diffuse bounce rays of the two-level scene against the flattened scene's, path
    // by path, from the same camera rays.
    const TwoLevelBuild b = build_two_level(test_meshes(), random_placements(40, 3, 30, 16));
    const FlatBuild f = flatten(b);
    for (uint32_t ii = 0; ii < uint32_t(b.instances.size()); ++ii) {
        const InstanceRecord& r = b.instances[ii];
        const MeshRecord& m = b.meshes[r.mesh];
        for (const TriangleRecord& t : b.mesh_tris[r.mesh]) {
            const TriangleRecord w = world_triangle(r, t);
            double v[3][3];
            b.world_triangle(ii, m.prim_first + t.prim, v);
            const float* wv[3] = {w.v0, w.v1, w.v2};
            double scale = 0;
            for (int k = 0; k < 3; ++k)
                for (int c = 0; c < 4; ++c) scale = std::max(scale, std::fabs(double(r.object_to_world[k][c])));
            for (int k = 0; k < 3; ++k)
                for (int a = 0; a < 3; ++a) {
                    // Three fmas: each rounds once; |terms| <= 4 scale max(|x|, 1).
                    const double mag = 4 * scale * std::max({1.0, std::fabs(double(t.v0[a])), std::fabs(double(t.v1[a])),
                                                             std::fabs(double(t.v2[a])), 10.0});
                    ASSERT_LE(std::fabs(double(wv[k][a]) - v[k][a]), 4 * kU * mag);
                }
            float n[3];
            if (!geometric_normal(w, n)) continue;
            double e1[3], e2[3];
            for (int a = 0; a < 3; ++a) {
                e1[a] = v[1][a] - v[0][a];
                e2[a] = v[2][a] - v[0][a];
            }
            const double nd[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2],
                                  e1[0] * e2[1] - e1[1] * e2[0]};
            EXPECT_GT(n[0] * nd[0] + n[1] * nd[1] + n[2] * nd[2], 0.0) << "instance " << ii;
        }
    }
    float lo[3], hi[3];
    world_box(b, lo, hi);
    Camera cam;
    for (int a = 0; a < 3; ++a) {
        cam.target[a] = 0.5f * (lo[a] + hi[a]);
        cam.eye[a] = cam.target[a] + 1.5f * (hi[a] - lo[a]) * (a == 2 ? 1.0f : 0.4f);
    }
    const std::vector<Ray> primary = camera_rays(cam, 96, 96);
    const DiffuseRays two = diffuse_rays(b.view(), primary, 1, 5, 1);
    const DiffuseRays flat = diffuse_rays(f.wide.nodes.data(), f.wide.nodes.size(), f.wide.tris.data(),
                                          f.wide.tris.size(), primary, 1, 5, 1);
    ASSERT_GT(flat.rays.size(), primary.size() / 10);
    size_t i = 0, j = 0, same = 0;
    while (i < two.rays.size() && j < flat.rays.size()) {
        if (two.path[i] < flat.path[j]) {
            ++i;
        } else if (two.path[i] > flat.path[j]) {
            ++j;
        } else {
            double dd = 0, od = 0;
            for (int a = 0; a < 3; ++a) {
                dd = std::max(dd, std::fabs(double(two.rays[i].dir[a]) - flat.rays[j].dir[a]));
                od = std::max(od, std::fabs(double(two.rays[i].org[a]) - flat.rays[j].org[a]));
            }
            same += dd <= 1e-4 && od <= 1e-4;
            ++i;
            ++j;
        }
    }
    std::printf("diffuse bounce: two-level %zu rays, flattened %zu, equal within 1e-4: %zu\n", two.rays.size(),
                flat.rays.size(), same);
    EXPECT_EQ(two.rays.size(), flat.rays.size());
    EXPECT_GE(same * 100, flat.rays.size() * 99);
}

/// A two-level file as a TwoLevelBuild (its sections as they are; mesh_tris rebuilt
/// from TRIS: one record per stored triangle of each mesh, prim made local).
TwoLevelBuild from_file(const File& f) {
    TwoLevelBuild b;
    b.tlas.assign(f.top_nodes().begin(), f.top_nodes().end());
    b.instances.assign(f.instances().begin(), f.instances().end());
    for (uint32_t i = 0; i < uint32_t(b.instances.size()); ++i) b.inst_placement.push_back(i);
    b.meshes.assign(f.meshes().begin(), f.meshes().end());
    b.nodes.assign(f.nodes().begin(), f.nodes().end());
    b.tris.assign(f.triangles().begin(), f.triangles().end());
    for (const MeshRecord& m : b.meshes) {
        std::vector<TriangleRecord> mt(m.prim_count);
        std::vector<bool> seen(m.prim_count, false);
        for (uint32_t k = m.tri_first; k < m.tri_first + m.tri_count; ++k) {
            const uint32_t p = b.tris.at(k).prim - m.prim_first;
            if (p < m.prim_count && !seen[p]) {
                seen[p] = true;
                mt[p] = b.tris[k];
                mt[p].prim = p;
            }
        }
        for (bool s : seen) EXPECT_TRUE(s) << "a stored triangle of a mesh has no TRIS record";
        b.mesh_tris.push_back(std::move(mt));
    }
    return b;
}

TEST(TwoLevel, SpecVectorFileMatchesItsFlattenedTwin) {
    // The format's two-level spec vector (spec/vectors/instanced.cwbvh: 2 meshes, 5
    // instances, mirrored and far-translated ones, written by the format's writer),
    // traced through the loader's accessors, against its flattened twin, with rays
    // aimed at each instance's world box.
    auto f = File::open(std::string(CWBVH_SOURCE_DIR) + "/spec/vectors/instanced.cwbvh");
    ASSERT_TRUE(f.ok()) << f.error().message;
    ASSERT_TRUE(f->is_two_level());
    const TwoLevelBuild b = from_file(*f);
    const FlatBuild flat = flatten(b);
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    bool mirrored = false;
    for (uint32_t ii = 0; ii < uint32_t(b.instances.size()); ++ii) {
        const InstanceRecord& r = b.instances[ii];
        mirrored = mirrored || det3(r.object_to_world) < 0;
        std::vector<Ray> rays;
        for (int i = 0; i < 2000; ++i) {
            float o[3], d[3];
            for (int a = 0; a < 3; ++a) {
                const double lo = r.world_lo[a], hi = r.world_hi[a], ext = hi - lo;
                const double target = lo + u(rng) * ext;
                o[a] = float(lo + (u(rng) * 4.0 - 1.5) * ext);
                d[a] = float(target - o[a]);
            }
            rays.push_back(make_ray(o, d));
        }
        const std::string what = "spec vector instance " + std::to_string(ii);
        const double tmag = std::max({std::fabs(double(r.object_to_world[0][3])),
                                      std::fabs(double(r.object_to_world[1][3])),
                                      std::fabs(double(r.object_to_world[2][3]))});
        if (tmag < 1000) {
            expect_agree(compare(b, flat, rays, trace_two_level(b, rays), trace_flat(flat, rays)), what.c_str());
            continue;
        }
        // Far from the origin the flattened twin is no reference (its vertices are
        // rounded to the float spacing there, ~1e-3 of this mesh); the exact (double)
        // intersection is: hit/miss agrees unless the ray passes within 1e-3
        // (barycentric) of an edge, and t is within the rounding bound of moving the
        // ray to object space (expect_inside_rays_hit's).
        const TwoLevelHits h = trace_two_level(b, rays);
        size_t hits = 0, wrong = 0, edge = 0, off = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            const double o[3] = {rays[i].org[0], rays[i].org[1], rays[i].org[2]};
            const double d[3] = {rays[i].dir[0], rays[i].dir[1], rays[i].dir[2]};
            double inside = INFINITY, near = INFINITY;
            const MeshRecord& m = b.meshes[r.mesh];
            for (const TriangleRecord& t : b.mesh_tris[r.mesh]) {
                double v[3][3];
                b.world_triangle(ii, m.prim_first + t.prim, v);
                const double ti = ray_tri_double(o, d, v, -1e-3), tn = ray_tri_double(o, d, v, 1e-3);
                if (ti == ti && ti >= 0) inside = std::min(inside, ti);
                if (tn == tn && tn >= 0) near = std::min(near, tn);
            }
            const bool hit = h.hits[i].prim != kMissPrim;
            hits += hit;
            if (hit && h.inst[i] != ii) continue;  // another instance in front
            if (hit != (inside < INFINITY)) {
                if (hit == (near < INFINITY)) ++edge;
                else ++wrong;
                continue;
            }
            if (!hit) continue;
            const double exact = exact_t(b, ii, rays[i]);
            const double omax = std::max({std::fabs(o[0]), std::fabs(o[1]), std::fabs(o[2])});
            const double dl = len(rays[i].dir);
            off += !(std::fabs(double(h.hits[i].t) - exact) * dl <= 16 * kU * (omax + exact * dl) + 1e-6 * exact * dl);
        }
        std::printf("%-28s rays %zu hits %zu  vs exact: hit/miss %zu (edge %zu)  t %zu\n", what.c_str(), rays.size(),
                    hits, wrong, edge, off);
        EXPECT_GT(hits, rays.size() / 10) << what;
        EXPECT_EQ(wrong, 0u) << what;
        EXPECT_LE(edge * 100, rays.size()) << what;
        EXPECT_EQ(off, 0u) << what;
    }
    ASSERT_TRUE(mirrored) << "the vector was meant to hold a mirrored instance";
}

}  // namespace
}  // namespace cwbvh::test
