// The default camera of `cwbvh rays` and `cwbvh render` for a scene's bounds.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"
#include "cwbvh/kernels/ray_gen.h"

namespace cwbvh::tool {

/// default_camera(b), refused (kBadInput naming `path`) when the bounds are not finite or the
/// camera it gives is not usable: an eye or target that overflowed float (bounds near ±FLT_MAX
/// put the eye at infinity, and every ray would be invalid), or an eye equal to the target
/// (a scene far from the origin and too small for float to separate the two).
inline Result scene_camera(const SceneBounds& b, const std::string& path, Camera& camera) {
    char box[160];
    std::snprintf(box, sizeof box, "[%g %g %g]-[%g %g %g]", double(b.lo[0]), double(b.lo[1]), double(b.lo[2]),
                  double(b.hi[0]), double(b.hi[1]), double(b.hi[2]));
    auto refuse = [&](const char* why) {
        return Result::fail(Status::kBadInput, 0,
                            path + ": cannot place the default camera for the scene bounds " + box + ": " + why +
                                " (give --camera)");
    };
    for (int a = 0; a < 3; ++a)
        if (!std::isfinite(b.lo[a]) || !std::isfinite(b.hi[a])) return refuse("bounds are not finite");
    const Camera c = default_camera(b);
    bool same = true;
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(c.eye[a]) || !std::isfinite(c.target[a])) return refuse("the eye would be at infinity");
        same = same && c.eye[a] == c.target[a];
    }
    if (same) return refuse("the eye would coincide with the target");
    camera = c;
    return Result::success();
}

}  // namespace cwbvh::tool
