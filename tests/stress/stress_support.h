// Support for the stress suite: compile a mesh through the compiler library into
// a temporary .cwbvh and open it; an Embree peer over the file's triangles; a
// culled exact oracle; mismatch classification against it.
//
// Culled oracle: the exact oracle (cwbvh/oracle/oracle.h) is brute force. Here each
// triangle is first tested against its bounding box, padded by 2^-20 of the box's
// magnitude plus the smallest normal float, with a double-precision slab test whose
// interval is widened by 1e-9 relative before comparing. Every box intersection
// that the exact ray/triangle test can find survives that test (the slab
// arithmetic in double on float inputs is far more accurate than the padding), so
// the culling only removes triangles the ray cannot touch; the answer is the exact
// oracle's. The t tolerance is the oracle's (2^-18 of |org| + scene extent, in
// units of |dir|).
#pragma once

#include <embree3/rtcore.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <random>
#include <vector>

#include "../result_util.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"
#include "cwbvh/oracle/oracle.h"
#include "traverse/test_scenes.h"

namespace cwbvh::stress {

using test::Mesh;

inline std::filesystem::path temp_dir() {
    auto d = std::filesystem::temp_directory_path() / ("cwbvh_stress_" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
}

/// Writes `m` as OBJ with 9 significant digits (float round trip is exact).
inline std::string write_obj(const Mesh& m, const std::string& name) {
    const std::string path = (temp_dir() / (name + ".obj")).string();
    FILE* f = std::fopen(path.c_str(), "w");
    if (!f) return {};
    for (size_t i = 0; i + 2 < m.v.size(); i += 3)
        std::fprintf(f, "v %.9g %.9g %.9g\n", m.v[i], m.v[i + 1], m.v[i + 2]);
    for (size_t i = 0; i + 2 < m.idx.size(); i += 3)
        std::fprintf(f, "f %u %u %u\n", m.idx[i] + 1, m.idx[i + 1] + 1, m.idx[i + 2] + 1);
    std::fclose(f);
    return path;
}

/// Compiles `input` (SBVH, --keep-sbvh) into the temp dir and opens it.
inline bool compile_and_open(const std::string& input, const std::string& name, File& out, std::string& error) {
    compiler::CompileOptions o;
    o.inputs = {input};
    o.output = (temp_dir() / (name + ".cwbvh")).string();
    o.keep_sbvh = true;
    o.threads = 2;
    compiler::CompileStats stats;
    if (!::cwbvh::test::ok(compiler::compile(o, stats), error)) return false;
    auto f = File::open(o.output);
    if (!f.ok()) {
        error = f.error().describe();
        return false;
    }
    out = std::move(f.value());
    return true;
}

/// Embree 3 scene over the file's stored triangles (one per prim), robust flag on.
class EmbreePeer {
public:
    explicit EmbreePeer(std::span<const TriangleRecord> tris, bool robust = true) {
        for (const TriangleRecord& t : tris) max_prim_ = std::max(max_prim_, t.prim);
        std::vector<const TriangleRecord*> by_prim(tris.empty() ? 0 : size_t(max_prim_) + 1, nullptr);
        for (const TriangleRecord& t : tris)
            if (!by_prim[t.prim]) by_prim[t.prim] = &t;
        for (const auto* t : by_prim)
            if (t) prims_.push_back(t);
        device_ = rtcNewDevice("threads=1");
        scene_ = rtcNewScene(device_);
        if (robust) rtcSetSceneFlags(scene_, RTC_SCENE_FLAG_ROBUST);
        rtcSetSceneBuildQuality(scene_, RTC_BUILD_QUALITY_HIGH);
        RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_TRIANGLE);
        float* v = static_cast<float*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3,
                                                               3 * sizeof(float), prims_.size() * 3));
        unsigned* idx = static_cast<unsigned*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                       3 * sizeof(unsigned), prims_.size()));
        for (size_t i = 0; i < prims_.size(); ++i) {
            for (int a = 0; a < 3; ++a) {
                v[(i * 3 + 0) * 3 + a] = prims_[i]->v0[a];
                v[(i * 3 + 1) * 3 + a] = prims_[i]->v1[a];
                v[(i * 3 + 2) * 3 + a] = prims_[i]->v2[a];
            }
            for (int k = 0; k < 3; ++k) idx[i * 3 + k] = unsigned(i * 3 + k);
        }
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene_, g);
        rtcReleaseGeometry(g);
        rtcCommitScene(scene_);
    }
    ~EmbreePeer() {
        rtcReleaseScene(scene_);
        rtcReleaseDevice(device_);
    }
    EmbreePeer(const EmbreePeer&) = delete;
    EmbreePeer& operator=(const EmbreePeer&) = delete;

    Hit intersect(const Ray& r) const {
        if (!ray_is_traceable(r)) return make_miss();
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRayHit rh{};
        set_ray(rh.ray, r);
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rtcIntersect1(scene_, &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return make_miss();
        return Hit{rh.ray.tfar, rh.hit.u, rh.hit.v, prims_[rh.hit.primID]->prim};
    }
    bool occluded(const Ray& r) const {
        if (!ray_is_traceable(r)) return false;
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        RTCRay ray{};
        set_ray(ray, r);
        rtcOccluded1(scene_, &ctx, &ray);
        return ray.tfar < 0.0f;  // Embree sets tfar = -inf on a hit
    }

private:
    static void set_ray(RTCRay& o, const Ray& r) {
        o.org_x = r.org[0];
        o.org_y = r.org[1];
        o.org_z = r.org[2];
        o.dir_x = r.dir[0];
        o.dir_y = r.dir[1];
        o.dir_z = r.dir[2];
        o.tnear = r.tmin;
        o.tfar = r.tmax;
        o.mask = 0xFFFFFFFFu;
        o.flags = 0;
        o.time = 0;
    }
    RTCDevice device_ = nullptr;
    RTCScene scene_ = nullptr;
    uint32_t max_prim_ = 0;
    std::vector<const TriangleRecord*> prims_;
};

/// Exact oracle with conservative box culling (see the file comment).
class CulledOracle {
public:
    explicit CulledOracle(std::span<const TriangleRecord> tris) {
        for (const TriangleRecord& t : tris) {
            if (seen_.size() <= t.prim) seen_.resize(size_t(t.prim) + 1, 0);
            if (seen_[t.prim]) continue;  // split references repeat a triangle
            seen_[t.prim] = 1;
            tris_.push_back(t);
            Box b;
            for (int a = 0; a < 3; ++a) {
                double lo = std::min({double(t.v0[a]), double(t.v1[a]), double(t.v2[a])});
                double hi = std::max({double(t.v0[a]), double(t.v1[a]), double(t.v2[a])});
                const double pad = std::max(std::fabs(lo), std::fabs(hi)) * 0x1p-20 + 1.2e-38;
                b.lo[a] = lo - pad;
                b.hi[a] = hi + pad;
                ext_ = std::max(ext_, std::max(std::fabs(lo), std::fabs(hi)));
            }
            boxes_.push_back(b);
        }
    }
    test::OracleResult trace(const Ray& r) const {
        if (!ray_is_traceable(r)) return {};
        long double m = 0, dl = 0;
        for (int a = 0; a < 3; ++a) {
            m = std::max(m, std::fabs((long double)r.org[a]));
            dl = std::max(dl, std::fabs((long double)r.dir[a]));
        }
        const long double tol = (m + ext_) / dl * 3.814697265625e-06L;  // 2^-18, as oracle_trace
        std::vector<TriangleRecord> cand;
        for (size_t i = 0; i < tris_.size(); ++i)
            if (box_hit(r, boxes_[i])) cand.push_back(tris_[i]);
        return test::oracle_trace(r, cand.data(), cand.size(), tol);
    }
    /// t of the line through the reported prim (false if the oracle says it misses).
    bool prim_t(const Ray& r, uint32_t prim, long double& t) const {
        for (const TriangleRecord& tri : tris_)
            if (tri.prim == prim) return test::oracle_hits_prim(r, &tri, 1, prim, t);
        return false;
    }
    size_t size() const { return tris_.size(); }

private:
    struct Box {
        double lo[3], hi[3];
    };
    static bool box_hit(const Ray& r, const Box& b) {
        // Slab test in double over the whole line (no tmin/tmax: the oracle applies
        // the range), intervals widened by 1e-9 relative.
        double t0 = -INFINITY, t1 = INFINITY;
        for (int a = 0; a < 3; ++a) {
            const double o = r.org[a], d = r.dir[a];
            if (d == 0.0) {
                if (o < b.lo[a] || o > b.hi[a]) return false;
                continue;
            }
            double ta = (b.lo[a] - o) / d, tb = (b.hi[a] - o) / d;
            if (ta > tb) std::swap(ta, tb);
            ta -= std::fabs(ta) * 1e-9;
            tb += std::fabs(tb) * 1e-9;
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
        }
        return t0 <= t1;
    }
    std::vector<TriangleRecord> tris_;
    std::vector<Box> boxes_;
    std::vector<uint8_t> seen_;
    double ext_ = 0;
};

/// Mismatch counts of one traversal against the oracle.
struct Tally {
    uint64_t rays = 0, oracle_hits = 0, agree = 0, ties = 0, false_miss = 0, false_hit = 0, wrong_prim = 0,
             t_error = 0, near_end = 0;
    double max_t_err = 0;  ///< in units of the oracle tolerance
    bool clean() const { return false_miss == 0 && false_hit == 0 && wrong_prim == 0 && t_error == 0; }
};

/// Either answer is right when the deciding hit lies within the tolerance of tmin
/// or tmax: the oracle's closest hit (when the traversal missed or reported
/// something else), or the reported triangle's exact t (a hit just outside the
/// range, e.g. the surface a diffuse ray leaves).
inline bool near_end(const Ray& r, const Hit& h, const test::OracleResult& o, const CulledOracle& oracle) {
    auto near = [&](long double t) {
        return std::fabs(t - (long double)r.tmin) <= o.tol || std::fabs(t - (long double)r.tmax) <= o.tol;
    };
    if (o.hit && near(o.t) && h.prim != o.prim) return true;
    long double tp = 0;
    return h.prim != kMissPrim && oracle.prim_t(r, h.prim, tp) && near(tp) && h.prim != o.prim;
}

/// Closest-hit check. t_tol_factor: a reported t may differ from the exact t by
/// this many oracle tolerances.
inline void classify_closest(const Ray& r, const Hit& h, const test::OracleResult& o, const CulledOracle& oracle,
                             Tally& s, double t_tol_factor = 4.0) {
    ++s.rays;
    if (o.hit) ++s.oracle_hits;
    if (near_end(r, h, o, oracle)) return void(++s.near_end);
    const bool hit = h.prim != kMissPrim;
    if (!o.hit && !hit) {
        ++s.agree;
        return;
    }
    if (o.hit && !hit) {
        ++s.false_miss;
        return;
    }
    if (!o.hit && hit) {
        ++s.false_hit;
        return;
    }
    long double tp = 0;
    const bool in_ties = std::find(o.ties.begin(), o.ties.end(), h.prim) != o.ties.end();
    if (!in_ties) {
        // Reported triangle is hit by the line at a t within tolerance of the closest: a tie.
        if (oracle.prim_t(r, h.prim, tp) && std::fabs(tp - o.t) <= o.tol) {
            ++s.ties;
        } else {
            ++s.wrong_prim;
            return;
        }
    }
    const double err = double(std::fabs((long double)h.t - o.t) / o.tol);
    s.max_t_err = std::max(s.max_t_err, err);
    if (err > t_tol_factor) {
        ++s.t_error;
        return;
    }
    if (in_ties) ++s.agree;
}

/// Any-hit check: hit/miss must agree; a reported prim must be hit in range.
inline void classify_any(const Ray& r, const Hit& h, const test::OracleResult& o, const CulledOracle& oracle,
                         Tally& s) {
    ++s.rays;
    if (o.hit) ++s.oracle_hits;
    if (near_end(r, h, o, oracle)) return void(++s.near_end);
    const bool hit = h.prim != kMissPrim;
    if (o.hit && !hit) {
        ++s.false_miss;
    } else if (!o.hit && hit) {
        ++s.false_hit;
    } else if (hit) {
        long double tp = 0;
        if (!oracle.prim_t(r, h.prim, tp) || tp < (long double)r.tmin - o.tol || tp > (long double)r.tmax + o.tol)
            ++s.wrong_prim;
        else
            ++s.agree;
    } else {
        ++s.agree;
    }
}

inline void print_tally_header() {
    std::printf("%-22s %-10s %-13s %7s %7s %6s %6s %6s %6s %6s %6s %8s\n", "scene", "rays", "method", "n", "o.hits",
                "agree", "ties", "fmiss", "fhit", "wprim", "terr", "maxterr");
}
inline void print_tally(const std::string& scene, const std::string& rays, const std::string& method, const Tally& s) {
    std::printf("%-22s %-10s %-13s %7llu %7llu %6llu %6llu %6llu %6llu %6llu %6llu %8.3g\n", scene.c_str(),
                rays.c_str(), method.c_str(), (unsigned long long)s.rays, (unsigned long long)s.oracle_hits,
                (unsigned long long)s.agree, (unsigned long long)s.ties, (unsigned long long)s.false_miss,
                (unsigned long long)s.false_hit, (unsigned long long)s.wrong_prim, (unsigned long long)s.t_error,
                s.max_t_err);
}

/// Random segments: origins in the scene bounds grown by 50 % per side, each aimed at
/// a point inside the bounds; every fourth ray has a finite tmax (0.75).
inline std::vector<Ray> random_rays(const SceneBounds& b, size_t n, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<Ray> rays;
    for (size_t i = 0; i < n; ++i) {
        Ray r;
        for (int a = 0; a < 3; ++a) {
            const double lo = b.lo[a], ext = double(b.hi[a]) - lo;
            const double o = lo + (u(rng) * 2.0 - 0.5) * ext;  // bounds grown by 50% per side
            const double t = lo + u(rng) * ext;                // a target inside the bounds
            r.org[a] = float(o);
            r.dir[a] = float(t - o);
        }
        r.tmin = 0.0f;
        r.tmax = (i % 4 == 3) ? 0.75f : kInfinity;  // some finite segments
        if (ray_is_traceable(r)) rays.push_back(r);
    }
    return rays;
}

/// Rays through the grid's interior vertices and edge midpoints exactly
/// (integer and half-integer points; z of the point read from the mesh, slopes
/// dyadic so that org + 4 dir is the point exactly).
inline std::vector<Ray> grid_point_rays(const Mesh& m, int n) {
    std::vector<Ray> rays;
    auto z_at = [&](int i, int j) { return m.v[size_t(j * (n + 1) + i) * 3 + 2]; };
    const float slopes[][2] = {{0.125f, 0.25f}, {-0.375f, 0.0f}, {0.0f, 0.0f}, {0.5f, -0.5f}};
    int k = 0;
    for (int j = 1; j < n; ++j)
        for (int i = 1; i < n; ++i)
            for (int e = 0; e < 3; ++e) {  // vertex, +x edge midpoint, diagonal-free +y edge midpoint
                const float px = float(i) + (e == 1 ? 0.5f : 0.0f), py = float(j) + (e == 2 ? 0.5f : 0.0f);
                // The point lies on the mesh only where the segment is straight in z: use vertices,
                // and midpoints of edges whose ends have equal z.
                float pz = z_at(i, j);
                if (e == 1 && z_at(i + 1, j) != pz) continue;
                if (e == 2 && z_at(i, j + 1) != pz) continue;
                const float* s = slopes[k++ % 4];
                const float d[3] = {s[0], s[1], -1.0f};
                const float o[3] = {px - 4 * d[0], py - 4 * d[1], pz + 4.0f};
                rays.push_back(test::make_ray(o, d));
                const float d2[3] = {-d[0], -d[1], 1.0f};  // from below
                const float o2[3] = {px - 4 * d2[0], py - 4 * d2[1], pz - 4.0f};
                rays.push_back(test::make_ray(o2, d2));
            }
    return rays;
}

/// Random segments (random_rays), camera rays of the default camera and their diffuse
/// bounce-1 rays: the stress tests' ray set for a compiled scene.
inline std::vector<Ray> scene_rays(const File& f, size_t n_random, uint32_t cam_size, uint32_t seed) {
    const SceneBounds& b = *f.bounds();
    std::vector<Ray> rays = random_rays(b, n_random, seed);
    const std::vector<Ray> primary = camera_rays(default_camera(b), cam_size, cam_size);
    const auto nodes = f.nodes();
    const auto tris = f.triangles();
    const DiffuseRays d = diffuse_rays(nodes.data(), nodes.size(), tris.data(), tris.size(), primary, 1, 7, 2);
    rays.insert(rays.end(), primary.begin(), primary.end());
    rays.insert(rays.end(), d.rays.begin(), d.rays.end());
    return rays;
}

/// A suite whose compiled test files live under temp_dir(), removed when it ends.
class TempDirSuite : public ::testing::Test {
protected:
    static void TearDownTestSuite() {
        std::error_code ec;
        std::filesystem::remove_all(temp_dir(), ec);
    }
};

}  // namespace cwbvh::stress
