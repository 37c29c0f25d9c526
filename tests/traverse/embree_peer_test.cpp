// Embree 3 (rtcIntersect1) as a peer on the same triangles: count agreements of
// hit/miss and primitive with the CWBVH traversal and with the exact oracle. Embree
// is not watertight (cwbvh-facts 3, item 16), so this reports rather than demands.
// Also a small CPU throughput report (Mrays/s) on the synthetic scenes.
#include <embree3/rtcore.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/oracle/oracle.h"
#include "traverse/test_scenes.h"

namespace cwbvh::test {
namespace {

struct EmbreeScene {
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    explicit EmbreeScene(const std::vector<TriangleRecord>& tris) {
        device = rtcNewDevice("threads=1");
        scene = rtcNewScene(device);
        rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
        RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
        float* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), tris.size() * 3));
        unsigned* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                       3 * sizeof(unsigned), tris.size()));
        for (size_t i = 0; i < tris.size(); ++i) {
            for (int a = 0; a < 3; ++a) {
                v[(i * 3 + 0) * 3 + a] = tris[i].v0[a];
                v[(i * 3 + 1) * 3 + a] = tris[i].v1[a];
                v[(i * 3 + 2) * 3 + a] = tris[i].v2[a];
            }
            for (int k = 0; k < 3; ++k) idx[i * 3 + k] = unsigned(i * 3 + k);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene, g);
        rtcReleaseGeometry(g);
        rtcCommitScene(scene);
    }
    ~EmbreeScene() {
        rtcReleaseScene(scene);
        rtcReleaseDevice(device);
    }
    Hit trace(const Ray& r, const std::vector<TriangleRecord>& tris) const {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh{};
        rh.ray.org_x = r.org[0];
        rh.ray.org_y = r.org[1];
        rh.ray.org_z = r.org[2];
        rh.ray.dir_x = r.dir[0];
        rh.ray.dir_y = r.dir[1];
        rh.ray.dir_z = r.dir[2];
        rh.ray.tnear = r.tmin;
        rh.ray.tfar = r.tmax;
        rh.ray.mask = 0xFFFFFFFFu;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene, &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return make_miss();
        return Hit{rh.ray.tfar, rh.hit.u, rh.hit.v, tris[rh.hit.primID].prim};
    }
};

TEST(EmbreePeer, AgreementCounts) {
    struct Case {
        const char* name;
        std::vector<TriangleRecord> tris;
        float lo, hi;
    };
    Mesh sphere = cube_mesh(48, true);
    std::vector<Case> cases;
    cases.push_back({"soup 3000", random_soup(3000, 100, 4, 41), -20, 120});
    cases.push_back({"closed sphere (from inside)", sphere.tris(), 12, 36});
    for (const Case& c : cases) {
        const WideBvh w = build_wide(c.tris);
        const EmbreeScene es(c.tris);
        std::mt19937 rng(42);
        std::uniform_real_distribution<float> p(c.lo, c.hi), d(-1, 1);
        uint64_t n = 0, ours_oracle = 0, embree_oracle = 0, ours_embree = 0, embree_miss_oracle_hit = 0;
        for (int i = 0; i < 3000; ++i) {
            Ray r;
            for (int a = 0; a < 3; ++a) {
                r.org[a] = p(rng);
                r.dir[a] = d(rng);
            }
            r.tmin = 0;
            r.tmax = INFINITY;
            LocalStack<kCpuStackSize> st;
            Hit ours;
            traverse_cwbvh<TriangleTest::kWatertight, HitMode::kClosest>(w.nodes.data(), uint32_t(w.nodes.size()),
                                                                         w.tris.data(), uint32_t(w.tris.size()), r,
                                                                         ours, st);
            const Hit em = es.trace(r, c.tris);
            const OracleResult o = oracle_trace(r, c.tris.data(), c.tris.size());
            auto agrees = [&](const Hit& h) {
                if ((h.prim != kMissPrim) != o.hit) return false;
                return !o.hit || std::find(o.ties.begin(), o.ties.end(), h.prim) != o.ties.end();
            };
            ++n;
            ours_oracle += agrees(ours);
            embree_oracle += agrees(em);
            ours_embree += ours.prim == em.prim;
            embree_miss_oracle_hit += o.hit && em.prim == kMissPrim;
        }
        std::printf("%-28s rays %llu: cwbvh==oracle %llu, embree==oracle %llu, cwbvh==embree %llu, embree false misses %llu\n",
                    c.name, (unsigned long long)n, (unsigned long long)ours_oracle, (unsigned long long)embree_oracle,
                    (unsigned long long)ours_embree, (unsigned long long)embree_miss_oracle_hit);
        EXPECT_EQ(ours_oracle, n);
        EXPECT_GE(embree_oracle, n * 99 / 100);
    }
}

TEST(Benchmark, CpuMraysPerSecond) {
    struct Case {
        const char* name;
        std::vector<TriangleRecord> tris;
        float lo, hi;
    };
    std::vector<Case> cases;
    cases.push_back({"soup 100k tris, rays in box", random_soup(100000, 100, 1.5f, 51), -10, 110});
    cases.push_back({"sphere 98k tris, from inside", cube_mesh(128, true).tris(), 40, 88});
    for (const Case& c : cases) {
        const WideBvh w = build_wide(c.tris);
        const Bvh2 b = build_bvh2(c.tris);
        std::mt19937 rng(52);
        std::uniform_real_distribution<float> p(c.lo, c.hi), d(-1, 1);
        std::vector<Ray> rays(200000);
        for (Ray& r : rays) {
            for (int a = 0; a < 3; ++a) {
                r.org[a] = p(rng);
                r.dir[a] = d(rng);
            }
            r.tmin = 0;
            r.tmax = INFINITY;
        }
        std::vector<Hit> hits(rays.size());
        for (TriangleTest t : {TriangleTest::kWatertight, TriangleTest::kFast}) {
            for (HitMode m : {HitMode::kClosest, HitMode::kAny}) {
                CpuTraceOptions o;
                o.test = t;
                o.mode = m;
                o.threads = 1;
                const CpuTraceStats s = trace_cwbvh_cpu(w.nodes.data(), w.nodes.size(), w.tris.data(), w.tris.size(),
                                                        rays.data(), hits.data(), rays.size(), o);
                const CpuTraceStats s2 = trace_bvh2_cpu(b.nodes.data(), b.nodes.size(), c.tris.data(), c.tris.size(),
                                                        rays.data(), hits.data(), rays.size(), o);
                std::printf("%-30s %-10s %-7s 1 thread: CWBVH %.2f Mrays/s (%.1f nodes, %.1f tris/ray)  BVH2 %.2f Mrays/s (%.1f nodes, %.1f tris/ray)\n",
                            c.name, t == TriangleTest::kWatertight ? "watertight" : "fast",
                            m == HitMode::kClosest ? "closest" : "any", s.rays / s.seconds / 1e6,
                            double(s.nodes_visited) / s.rays, double(s.triangles_tested) / s.rays,
                            s2.rays / s2.seconds / 1e6, double(s2.nodes_visited) / s2.rays,
                            double(s2.triangles_tested) / s2.rays);
                EXPECT_EQ(s.stack_overflows + s.bad_indices, 0u);
            }
        }
        CpuTraceOptions o;
        o.threads = 2;
        const CpuTraceStats s = trace_cwbvh_cpu(w.nodes.data(), w.nodes.size(), w.tris.data(), w.tris.size(),
                                                rays.data(), hits.data(), rays.size(), o);
        std::printf("%-30s watertight closest 2 threads: CWBVH %.2f Mrays/s (wide depth %d, %zu nodes)\n", c.name,
                    s.rays / s.seconds / 1e6, w.depth, w.nodes.size());
    }
}

}  // namespace
}  // namespace cwbvh::test
