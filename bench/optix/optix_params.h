// Launch parameters shared by the OptiX peer's host code (optix_peer.cpp) and its
// device programs (optix_programs.cu). Rays and hits are the project's own records
// (cwbvh/kernels/ray.h, spec/rays.md), so the peer reads the same device buffers as
// the CWBVH and BVH2 kernels and writes hits the GPU check compares unchanged.
#pragma once

#include <optix_types.h>

#include "cwbvh/kernels/ray.h"

namespace cwbvh::optix_peer {

struct LaunchParams {
    const Ray* rays;              ///< n device rays
    Hit* hits;                    ///< n device hits
    OptixTraversableHandle gas;   ///< the one GAS: primitive i = stored triangle i
    unsigned int any;             ///< 1: any hit (terminate on first hit), 0: closest hit
};

}  // namespace cwbvh::optix_peer
