// Ray and hit records: the in-memory layout used by every traversal and the
// record layout of the ray and hit files (normative description: spec/rays.md).
#pragma once

#include <cstddef>
#include <cstdint>

#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/fp.h"

namespace cwbvh {

/// A ray segment: the points org + t * dir for tmin <= t <= tmax (closed interval;
/// hits exactly at tmin or tmax count). dir need not be normalized; t is in units
/// of |dir|. Two 16-byte loads on the GPU.
struct Ray {
    float org[3];
    float tmin;
    float dir[3];
    float tmax;
};
static_assert(sizeof(Ray) == 32);
static_assert(offsetof(Ray, tmin) == 12);
static_assert(offsetof(Ray, dir) == 16);
static_assert(offsetof(Ray, tmax) == 28);

inline constexpr uint32_t kMissPrim = 0xFFFFFFFFu;

/// Result of one ray. prim is the stored triangle id (TriangleRecord::prim, an
/// index into PMAP), kMissPrim for a miss. u and v are the barycentric weights of
/// v1 and v2 (the hit point is (1-u-v)*v0 + u*v1 + v*v2, Embree's convention).
/// A miss has t = +inf, u = v = 0. One 16-byte store on the GPU.
struct Hit {
    float t;
    float u;
    float v;
    uint32_t prim;
};
static_assert(sizeof(Hit) == 16);
static_assert(offsetof(Hit, prim) == 12);

CWBVH_HD CWBVH_INLINE Hit make_miss() { return Hit{kInfinity, 0.0f, 0.0f, kMissPrim}; }

/// The hit record of a two-level scene (hit file 1.1, 20 bytes): a Hit and the
/// INST index of the instance hit (kInvalidIndex = 0xFFFFFFFF for a miss). In
/// memory the traversals keep the 16-byte Hit and write the instance ids to a
/// separate array (the single-level kernels' store stays one 16-byte write).
struct InstanceHit {
    float t;
    float u;
    float v;
    uint32_t prim;
    uint32_t instance;
};
static_assert(sizeof(InstanceHit) == 20);
static_assert(offsetof(InstanceHit, prim) == 12);
static_assert(offsetof(InstanceHit, instance) == 16);

/// The rays every traversal answers with a miss without touching the tree
/// (spec/rays.md, "Defined answers"): any NaN or infinite origin or direction
/// component, a zero direction (all three components +-0), a NaN tmin or tmax,
/// or tmin > tmax. Rays that pass are "traceable"; tmin = -inf and tmax = +inf
/// are allowed.
CWBVH_HD CWBVH_INLINE bool ray_is_traceable(const Ray& r) {
    for (int a = 0; a < 3; ++a) {
        if (!is_finite_f(r.org[a]) || !is_finite_f(r.dir[a])) return false;
    }
    if (r.dir[0] == 0.0f && r.dir[1] == 0.0f && r.dir[2] == 0.0f) return false;
    if (is_nan_f(r.tmin) || is_nan_f(r.tmax)) return false;
    return r.tmin <= r.tmax;
}

// ---------------------------------------------------------------------------
// Ray and hit files (spec/rays.md): a 32-byte header, then the records.
// ---------------------------------------------------------------------------

inline constexpr uint8_t kRayFileMagic[8] = {0xAB, 'C', 'W', 'R', 'A', 'Y', 0x0D, 0x0A};
inline constexpr uint8_t kHitFileMagic[8] = {0xAB, 'C', 'W', 'H', 'I', 'T', 0x0D, 0x0A};
inline constexpr uint16_t kRayFileVersionMajor = 1;
inline constexpr uint16_t kRayFileVersionMinor = 0;  ///< written with 32-byte rays and 16-byte hits
/// Minor version of a hit file with 20-byte InstanceHit records (two-level scenes).
/// Files with 16-byte records are still written as 1.0, byte for byte as before.
inline constexpr uint16_t kHitFileInstanceMinor = 1;

enum HitFileFlags : uint32_t {
    kHitFileAnyHit = 1u << 0,      ///< produced by an any-hit (occlusion) query
    kHitFileWatertight = 1u << 1,  ///< produced with the watertight triangle test
};

struct RayFileHeader {
    uint8_t magic[8];        ///< kRayFileMagic or kHitFileMagic
    uint16_t version_major;  ///< 1; a reader rejects an unknown major
    uint16_t version_minor;  ///< 0 (1 for InstanceHit records); a reader accepts a newer minor
    uint32_t record_size;    ///< 32 (Ray), 16 (Hit) or, from minor 1, 20 (InstanceHit)
    uint64_t count;          ///< number of records
    uint32_t flags;          ///< ray file: 0; hit file: HitFileFlags
    uint32_t reserved;       ///< must be 0
};
static_assert(sizeof(RayFileHeader) == 32);
static_assert(offsetof(RayFileHeader, version_major) == 8);
static_assert(offsetof(RayFileHeader, record_size) == 12);
static_assert(offsetof(RayFileHeader, count) == 16);
static_assert(offsetof(RayFileHeader, flags) == 24);

}  // namespace cwbvh
