// The OptiX peer's device programs, compiled to OptiX IR (nvcc -optix-ir; CUDA 13's
// nvcc no longer emits PTX for OptiX) and embedded in cwbvh_optix_peer.
//
// One ray per launch index, read from the same Ray records the CWBVH and BVH2 kernels
// read; one Hit written per ray: closest hit (t, barycentrics u of v1 and v, of v2:
// OptiX and ray.h share Embree's convention; prim = the GAS primitive index, which is
// the stored triangle id because optix_peer.cpp builds the GAS in stored-id order), or
// make_miss(). Rays ray.h calls untraceable are answered with a miss without tracing,
// as the project's traversals do (spec/rays.md, "Defined answers").
#include <optix.h>

#include "optix_params.h"

using cwbvh::Hit;
using cwbvh::Ray;

extern "C" {
__constant__ cwbvh::optix_peer::LaunchParams params;
}

extern "C" __global__ void __raygen__trace() {
    const unsigned int i = optixGetLaunchIndex().x;
    const Ray r = params.rays[i];
    Hit h = cwbvh::make_miss();
    if (cwbvh::ray_is_traceable(r)) {
        // Payload: t, u, v, prim; it starts as the miss record and only the closest-hit
        // program changes it (the miss program leaves it alone).
        unsigned int p0 = __float_as_uint(h.t), p1 = 0u, p2 = 0u, p3 = cwbvh::kMissPrim;
        // OptiX traces t in [tmin, tmax] with tmin >= 0: every ray the benchmark makes
        // (camera rays, diffuse bounces) starts at t >= 0, so the clamp changes none of them.
        // tmax: kept finite, as OptiX's SDK samples keep it (1e16f there): +inf (our camera
        // rays) becomes 1e30, beyond any hit in these scenes (extents below 1e6).
        const float tmin = fmaxf(r.tmin, 0.0f);
        const float tmax = fminf(r.tmax, 1e30f);
        const unsigned int flags = params.any ? (OPTIX_RAY_FLAG_DISABLE_ANYHIT | OPTIX_RAY_FLAG_TERMINATE_ON_FIRST_HIT)
                                              : OPTIX_RAY_FLAG_DISABLE_ANYHIT;
        if (tmin <= tmax)
            optixTrace(params.gas, make_float3(r.org[0], r.org[1], r.org[2]),
                       make_float3(r.dir[0], r.dir[1], r.dir[2]), tmin, tmax, 0.0f, OptixVisibilityMask(255), flags,
                       0u, 1u, 0u, p0, p1, p2, p3);
        h = Hit{__uint_as_float(p0), __uint_as_float(p1), __uint_as_float(p2), p3};
    }
    params.hits[i] = h;
}

extern "C" __global__ void __miss__miss() {}

extern "C" __global__ void __closesthit__hit() {
    const float2 b = optixGetTriangleBarycentrics();
    optixSetPayload_0(__float_as_uint(optixGetRayTmax()));
    optixSetPayload_1(__float_as_uint(b.x));
    optixSetPayload_2(__float_as_uint(b.y));
    optixSetPayload_3(optixGetPrimitiveIndex());
}
