// The camera of `cwbvh rays` and `cwbvh render`: their --camera, --view, --views and
// --scene options, and the one rule that turns them into a camera.
//   --camera            that camera;
//   --view NAME|N       the view NAME (or the N-th, 1-based) of the scene in the view
//                       catalog (view_catalog.h: --views, else $CWBVH_VIEWS, else the
//                       compiled-in views/catalog.txt);
//   neither             the scene's first catalog view, else (a scene not in the catalog,
//                       or no compiled-in catalog) default_camera for the file's bounds.
// The scene key is FILE's stem unless --scene gives it. A bad --view, or --view with
// --camera, is a usage error (exit 2); an unreadable or malformed catalog is bad input
// (exit 1), except that a missing compiled-in catalog (neither --views nor
// $CWBVH_VIEWS) without --view falls back to the default camera.
#pragma once

#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray_gen.h"

namespace cwbvh::tool {

struct CameraOptions {
    const char* camera = nullptr;  ///< --camera
    const char* view = nullptr;    ///< --view
    const char* views = nullptr;   ///< --views
    const char* scene = nullptr;   ///< --scene
    /// Takes argv[i] (advancing i past its value) when it is one of the four options:
    /// 1 taken, 0 not one of them, -1 a usage error already printed ("VERB: ...").
    int parse(const char* verb, int argc, char** argv, int& i);
    /// The files the camera reads besides the scene (the catalog): an output must differ.
    std::vector<std::string> inputs(const std::string& scene_path) const;
};

/// The camera for the scene at `path` with bounds `b` (rule above). Returns 0, or the
/// exit code after printing one error line ("VERB: ..."). `note` describes the view used
/// ("bunny front (first of 1, views/catalog.txt:35)", "--camera", "default camera (...)").
int choose_camera(const char* verb, const std::string& path, const SceneBounds& b, const CameraOptions& o,
                  Camera& camera, std::string& note);

}  // namespace cwbvh::tool
