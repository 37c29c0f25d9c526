// Reproducible ray generation for `cwbvh rays`, `cwbvh render`, the stress tests
// and the CPU benchmark: pinhole camera rays and the diffuse bounce rays of the
// paper's benchmark (Ylitie et al. 2017, section 5: rays spawned at the hit points
// of the previous bounce, cosine-distributed around the surface normal). Host only.
// Library: cwbvh_cpu_trace.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/ray_sampling.h"
#include "cwbvh/kernels/traverse_two_level.h"

namespace cwbvh {

struct Camera {
    float eye[3];
    float target[3];
    float fov_deg = 45.0f;  ///< vertical field of view
};

/// Looks at the centre of `b` from the direction (1, 1, 2) (above, right, in front
/// along +z; up = +y), at the distance where the bounding sphere of `b` fills the
/// 45-degree vertical field of view.
Camera default_camera(const SceneBounds& b);

/// "ex,ey,ez,tx,ty,tz,fov" (seven finite numbers, 0 < fov < 180, eye != target);
/// kInvalidArgument with a message starting "--camera: " otherwise.
Result parse_camera(const std::string& text, Camera& camera);

/// width * height rays through the pixel centres, row 0 at the top, row-major;
/// unit-length directions, tmin = 0, tmax = +inf. Up is +y (+z when looking along y).
std::vector<Ray> camera_rays(const Camera& camera, uint32_t width, uint32_t height);

// pcg_hash, random_unit and offset_ray_origin: ray_sampling.h (host and device code).

/// stored triangle id (TriangleRecord::prim) -> one of its records (SBVH spatial
/// splits may store a triangle more than once, always with the same vertices).
class PrimTable {
public:
    PrimTable(const TriangleRecord* tris, size_t count);
    /// nullptr when `prim` is not in the file.
    const TriangleRecord* find(uint32_t prim) const;

private:
    const TriangleRecord* tris_;
    std::vector<uint32_t> index_;
};

/// Unit geometric normal (v1 - v0) x (v2 - v0) in double; false for a triangle
/// whose normal is zero in double.
bool geometric_normal(const TriangleRecord& tri, float n[3]);

/// The diffuse ray leaving hit `hit` of `in` on `tri`: hit point from the
/// barycentrics (more accurate than org + t dir), normal flipped to face the
/// incoming ray, origin offset by offset_ray_origin, cosine-weighted direction
/// (Malley's method) in an orthonormal basis (Duff et al. 2017, "Building an
/// Orthonormal Basis, Revisited", JCGT 6(1)). tmin = 0, tmax = `tmax`.
/// False when the hit point or normal is not finite.
bool diffuse_ray(const Ray& in, const Hit& hit, const TriangleRecord& tri, uint32_t seed, uint32_t path,
                 uint32_t bounce, float tmax, Ray& out);

struct DiffuseRays {
    std::vector<Ray> rays;       ///< the rays of the last bounce, in path order
    std::vector<uint32_t> path;  ///< path (pixel) index of each ray
};

/// One bounce of the diffuse benchmark paths: for each ray of `cur` whose closest hit
/// `hits[i]` is a hit, the diffuse ray leaving it (diffuse_ray with `seed`, the ray's
/// path index and `bounce`, tmax = +inf), in path order. Misses (and hits whose
/// triangle is not in `table`, or whose ray is not finite) end their path.
/// hits.size() == cur.rays.size().
DiffuseRays next_bounce(const PrimTable& table, const DiffuseRays& cur, const std::vector<Hit>& hits, uint32_t seed,
                        uint32_t bounce);

/// The paper's diffuse benchmark rays: trace `primary` (closest hit, watertight,
/// CWBVH CPU traversal with `threads`), spawn one diffuse ray per hit, repeat
/// `bounces` times, and return the rays of bounce `bounces` of the paths still
/// alive (misses end a path). bounces >= 1. Deterministic for any thread count.
DiffuseRays diffuse_rays(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count,
                         const std::vector<Ray>& primary, uint32_t bounces, uint32_t seed, unsigned threads);

// ---------------------------------------------------------------------------
// Two-level scenes (format 1.2): a hit names an instance and a triangle of its mesh,
// whose record is in object space; the shading and bounce code above wants the
// world-space triangle, which world_triangle makes.
// ---------------------------------------------------------------------------

/// `tri` (object space) moved to world space by the instance's object_to_world
/// (transform_point, the normative fma order), prim kept. The winding is kept, so
/// a mirrored instance's world normal (geometric_normal) is flipped with it, as the
/// flattened scene's would be.
TriangleRecord world_triangle(const InstanceRecord& inst, const TriangleRecord& tri);

/// The world-space triangle of a two-level hit (prim of instance `instance`);
/// false when either index is not in the scene. `table` indexes scene.tris.
bool world_hit_triangle(const TwoLevelScene& scene, const PrimTable& table, uint32_t instance, uint32_t prim,
                        TriangleRecord& out);

/// next_bounce for a two-level scene: instances[i] is hit i's INST index.
DiffuseRays next_bounce(const TwoLevelScene& scene, const PrimTable& table, const DiffuseRays& cur,
                        const std::vector<Hit>& hits, const std::vector<uint32_t>& instances, uint32_t seed,
                        uint32_t bounce);

/// diffuse_rays over a two-level scene (trace_two_level_cpu, closest hit, watertight).
DiffuseRays diffuse_rays(const TwoLevelScene& scene, const std::vector<Ray>& primary, uint32_t bounces,
                         uint32_t seed, unsigned threads);

}  // namespace cwbvh
