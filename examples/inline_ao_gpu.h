// inline_ao's GPU path (inline_ao_gpu.cu, built with CUDA).
#pragma once

#include <string>
#include <vector>

#include "inline_ao.h"

namespace cwbvh::example {

/// Runs ao_pixel for every pixel in a kernel (one thread per pixel) over `scene`
/// (DeviceScene::view(): device pointers), downloads the image into `ao` (width * height
/// values). False with `error` set on a CUDA failure; kernel_ms: the kernel's time.
bool render_ao_gpu(const SceneView& scene, const AoCamera& camera, std::vector<float>& ao, float& kernel_ms,
                   std::string& error);

}  // namespace cwbvh::example
