// inline_ao's GPU path (inline_ao_gpu.cu, built with CUDA).
#pragma once

#include <string>
#include <vector>

#include "cwbvh/kernels/ray.h"

#include "inline_ao.h"

namespace cwbvh::example {

/// Runs ao_pixel for every camera ray in a kernel (one thread per pixel) over `scene`
/// (DeviceScene::view(): device pointers), downloads the image into `ao` (one value per
/// ray). False with `error` set on a CUDA failure; kernel_ms: the kernel's time.
bool render_ao_gpu(const SceneView& scene, const AoParams& params, const std::vector<Ray>& rays,
                   std::vector<float>& ao, float& kernel_ms, std::string& error);

}  // namespace cwbvh::example
