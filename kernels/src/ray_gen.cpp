// Ray generation (see ray_gen.h).
#include "cwbvh/kernels/ray_gen.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/fp.h"

namespace cwbvh {
namespace {

constexpr double kPi = 3.14159265358979323846;

void normalize(double v[3]) {
    const double l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int a = 0; a < 3; ++a) v[a] /= l;
}
void cross(const double a[3], const double b[3], double o[3]) {
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

}  // namespace

Camera default_camera(const SceneBounds& b) {
    Camera c;
    double center[3], radius2 = 0;
    for (int a = 0; a < 3; ++a) {
        center[a] = 0.5 * (double(b.lo[a]) + double(b.hi[a]));
        const double h = 0.5 * (double(b.hi[a]) - double(b.lo[a]));
        radius2 += h * h;
    }
    double radius = std::sqrt(radius2);
    if (!(radius > 0) || !std::isfinite(radius)) radius = 1.0;
    c.fov_deg = 45.0f;
    const double dist = radius / std::sin(0.5 * c.fov_deg * kPi / 180.0) * 1.02;
    double d[3] = {1, 1, 2};
    normalize(d);
    for (int a = 0; a < 3; ++a) {
        c.target[a] = float(center[a]);
        c.eye[a] = float(center[a] + d[a] * dist);
    }
    return c;
}

Result parse_camera(const std::string& text, Camera& camera) {
    auto bad = [](std::string what) { return Result::fail(Status::kInvalidArgument, 0, std::move(what)); };
    double v[7];
    const char* p = text.c_str();
    for (int i = 0; i < 7; ++i) {
        char* end = nullptr;
        errno = 0;
        v[i] = std::strtod(p, &end);
        if (end == p || errno != 0 || !std::isfinite(v[i]) || std::fabs(v[i]) > 3.0e38) {
            return bad("--camera: expected ex,ey,ez,tx,ty,tz,fov (7 finite numbers), got '" + text + "'");
        }
        p = end;
        if (i < 6) {
            if (*p != ',') {
                return bad("--camera: expected 7 comma-separated numbers, got '" + text + "'");
            }
            ++p;
        }
    }
    if (*p != '\0') {
        return bad("--camera: trailing characters in '" + text + "'");
    }
    if (!(v[6] > 0 && v[6] < 180)) {
        return bad("--camera: fov must be in (0, 180) degrees");
    }
    if (v[0] == v[3] && v[1] == v[4] && v[2] == v[5]) {
        return bad("--camera: eye and target are the same point");
    }
    for (int a = 0; a < 3; ++a) {
        camera.eye[a] = float(v[a]);
        camera.target[a] = float(v[3 + a]);
    }
    camera.fov_deg = float(v[6]);
    return Result::success();
}

std::vector<Ray> camera_rays(const Camera& c, uint32_t width, uint32_t height) {
    double fwd[3], up[3] = {0, 1, 0}, right[3], cup[3];
    for (int a = 0; a < 3; ++a) fwd[a] = double(c.target[a]) - double(c.eye[a]);
    normalize(fwd);
    if (std::fabs(fwd[1]) > 0.999) {  // looking straight up or down: use +z as up
        up[1] = 0;
        up[2] = 1;
    }
    cross(fwd, up, right);
    normalize(right);
    cross(right, fwd, cup);
    const double th = std::tan(0.5 * double(c.fov_deg) * kPi / 180.0);
    const double aspect = double(width) / double(height ? height : 1);
    std::vector<Ray> rays(size_t(width) * height);
    for (uint32_t y = 0; y < height; ++y)
        for (uint32_t x = 0; x < width; ++x) {
            const double sx = (2.0 * (x + 0.5) / width - 1.0) * th * aspect;
            const double sy = (1.0 - 2.0 * (y + 0.5) / height) * th;
            double d[3];
            for (int a = 0; a < 3; ++a) d[a] = fwd[a] + sx * right[a] + sy * cup[a];
            normalize(d);
            Ray& r = rays[size_t(y) * width + x];
            for (int a = 0; a < 3; ++a) {
                r.org[a] = c.eye[a];
                r.dir[a] = float(d[a]);
            }
            r.tmin = 0.0f;
            r.tmax = kInfinity;
        }
    return rays;
}

PrimTable::PrimTable(const TriangleRecord* tris, size_t count) : tris_(tris) {
    // A valid file's prims lie below its stored triangle count, itself at most the TRIS
    // count; a larger one (records changed after validation, e.g. a mapped file rewritten in
    // place) is left out, instead of sizing the table by it (2^32 entries: 16 GiB).
    uint32_t max_prim = 0;
    for (size_t i = 0; i < count; ++i)
        if (tris[i].prim < count) max_prim = tris[i].prim > max_prim ? tris[i].prim : max_prim;
    index_.assign(count ? size_t(max_prim) + 1 : 0, kMissPrim);
    for (size_t i = 0; i < count; ++i)
        if (tris[i].prim < count && index_[tris[i].prim] == kMissPrim) index_[tris[i].prim] = uint32_t(i);
}

const TriangleRecord* PrimTable::find(uint32_t prim) const {
    if (prim >= index_.size() || index_[prim] == kMissPrim) return nullptr;
    return tris_ + index_[prim];
}

bool geometric_normal(const TriangleRecord& t, float n[3]) {
    double e1[3], e2[3], c[3];
    for (int a = 0; a < 3; ++a) {
        e1[a] = double(t.v1[a]) - t.v0[a];
        e2[a] = double(t.v2[a]) - t.v0[a];
    }
    cross(e1, e2, c);
    const double l = std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
    if (!(l > 0) || !std::isfinite(l)) return false;
    for (int a = 0; a < 3; ++a) n[a] = float(c[a] / l);
    return true;
}

bool diffuse_ray(const Ray& in, const Hit& hit, const TriangleRecord& tri, uint32_t seed, uint32_t path,
                 uint32_t bounce, float tmax, Ray& out) {
    float n[3];
    if (!geometric_normal(tri, n)) return false;
    if (double(n[0]) * in.dir[0] + double(n[1]) * in.dir[1] + double(n[2]) * in.dir[2] > 0)
        for (float& x : n) x = -x;
    float p[3];
    for (int a = 0; a < 3; ++a) {
        const double q = double(tri.v0[a]) + double(hit.u) * (double(tri.v1[a]) - tri.v0[a]) +
                         double(hit.v) * (double(tri.v2[a]) - tri.v0[a]);
        p[a] = float(q);
        if (!is_finite_f(p[a])) return false;
    }
    offset_ray_origin(p, n, out.org);
    float t1[3], t2[3];
    orthonormal_basis(n, t1, t2);
    // Malley's method: uniform on the disk, projected up = cosine-weighted.
    const double u1 = random_unit(seed, path, bounce, 0), u2 = random_unit(seed, path, bounce, 1);
    const double r = std::sqrt(u1), phi = 2.0 * kPi * u2;
    const double lx = r * std::cos(phi), ly = r * std::sin(phi), lz = std::sqrt(std::max(0.0, 1.0 - u1));
    double d[3];
    for (int k = 0; k < 3; ++k) d[k] = lx * t1[k] + ly * t2[k] + lz * n[k];
    normalize(d);
    for (int k = 0; k < 3; ++k) out.dir[k] = float(d[k]);
    out.tmin = 0.0f;
    out.tmax = tmax;
    return ray_is_traceable(out);
}

namespace {
/// Bounce 0 of every path: the primary rays, path i = ray i.
DiffuseRays start_paths(const std::vector<Ray>& primary) {
    DiffuseRays cur;
    cur.rays = primary;
    cur.path.resize(primary.size());
    for (size_t i = 0; i < primary.size(); ++i) cur.path[i] = uint32_t(i);
    return cur;
}
}  // namespace

DiffuseRays diffuse_rays(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count,
                         const std::vector<Ray>& primary, uint32_t bounces, uint32_t seed, unsigned threads) {
    const PrimTable table(tris, tri_count);
    DiffuseRays cur = start_paths(primary);
    CpuTraceOptions opt;
    opt.threads = threads;
    std::vector<Hit> hits;
    for (uint32_t b = 1; b <= bounces; ++b) {
        hits.resize(cur.rays.size());
        (void)trace_cwbvh_cpu(nodes, node_count, tris, tri_count, cur.rays.data(), hits.data(), cur.rays.size(), opt);
        cur = next_bounce(table, cur, hits, seed, b);
    }
    return cur;
}

DiffuseRays next_bounce(const PrimTable& table, const DiffuseRays& cur, const std::vector<Hit>& hits, uint32_t seed,
                        uint32_t bounce) {
    DiffuseRays next;
    for (size_t i = 0; i < cur.rays.size() && i < hits.size(); ++i) {
        if (hits[i].prim == kMissPrim) continue;
        const TriangleRecord* t = table.find(hits[i].prim);
        Ray r;
        if (t && diffuse_ray(cur.rays[i], hits[i], *t, seed, cur.path[i], bounce, kInfinity, r)) {
            next.rays.push_back(r);
            next.path.push_back(cur.path[i]);
        }
    }
    return next;
}

TriangleRecord world_triangle(const InstanceRecord& inst, const TriangleRecord& tri) {
    TriangleRecord w = tri;
    transform_point(inst.object_to_world, tri.v0, w.v0);
    transform_point(inst.object_to_world, tri.v1, w.v1);
    transform_point(inst.object_to_world, tri.v2, w.v2);
    return w;
}

bool world_hit_triangle(const TwoLevelScene& scene, const PrimTable& table, uint32_t instance, uint32_t prim,
                        TriangleRecord& out) {
    if (instance >= scene.instance_count) return false;
    const TriangleRecord* t = table.find(prim);
    if (!t) return false;
    out = world_triangle(scene.instances[instance], *t);
    return true;
}

DiffuseRays next_bounce(const TwoLevelScene& scene, const PrimTable& table, const DiffuseRays& cur,
                        const std::vector<Hit>& hits, const std::vector<uint32_t>& instances, uint32_t seed,
                        uint32_t bounce) {
    DiffuseRays next;
    for (size_t i = 0; i < cur.rays.size() && i < hits.size() && i < instances.size(); ++i) {
        if (hits[i].prim == kMissPrim) continue;
        TriangleRecord t;
        Ray r;
        if (world_hit_triangle(scene, table, instances[i], hits[i].prim, t) &&
            diffuse_ray(cur.rays[i], hits[i], t, seed, cur.path[i], bounce, kInfinity, r)) {
            next.rays.push_back(r);
            next.path.push_back(cur.path[i]);
        }
    }
    return next;
}

DiffuseRays diffuse_rays(const TwoLevelScene& scene, const std::vector<Ray>& primary, uint32_t bounces,
                         uint32_t seed, unsigned threads) {
    const PrimTable table(scene.tris, scene.tri_count);
    DiffuseRays cur = start_paths(primary);
    CpuTraceOptions opt;
    opt.threads = threads;
    std::vector<Hit> hits;
    std::vector<uint32_t> instances;
    for (uint32_t b = 1; b <= bounces; ++b) {
        hits.resize(cur.rays.size());
        instances.resize(cur.rays.size());
        (void)trace_two_level_cpu(scene, cur.rays.data(), hits.data(), instances.data(), cur.rays.size(), opt);
        cur = next_bounce(scene, table, cur, hits, instances, seed, b);
    }
    return cur;
}

}  // namespace cwbvh
