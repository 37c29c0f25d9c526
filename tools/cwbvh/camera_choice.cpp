// The camera of `cwbvh rays` and `cwbvh render`: see camera_choice.h.
#include "camera_choice.h"

#include <cstring>

#include "args.h"
#include "commands.h"
#include "cwbvh/kernels/view_catalog.h"
#include "scene_camera.h"

namespace cwbvh::tool {

int CameraOptions::parse(const char* verb, int argc, char** argv, int& i) {
    const std::string a = argv[i], v = verb;
    auto take = [&](const char*& dst, const char* what) {
        dst = option_value(argc, argv, i);
        if (dst && *dst) return 1;
        error(kExitUsage, (v + ": " + a + " needs " + what).c_str());
        return -1;
    };
    if (a == "--camera") return take(camera, "a value");
    if (a == "--view") return take(view, "a view name or a 1-based index");
    if (a == "--views") return take(views, "a catalog path");
    if (a == "--scene") return take(scene, "a scene key");
    return 0;
}

std::vector<std::string> CameraOptions::inputs(const std::string& scene_path) const {
    return {scene_path, views ? std::string(views) : default_view_catalog_path()};
}

int choose_camera(const char* verb, const std::string& path, const SceneBounds& b, const CameraOptions& o,
                  Camera& camera, std::string& note) {
    const std::string v = verb;
    if (o.camera && o.view) return error(kExitUsage, (v + ": --camera and --view exclude each other").c_str());
    if (o.camera) {
        if (const Result r = parse_camera(o.camera, camera); !r.ok())
            return error(kExitUsage, (v + ": " + r.message).c_str());
        note = "--camera";
        return 0;
    }
    const std::string scene = o.scene ? o.scene : scene_key(path);
    ViewCatalog catalog;
    CatalogLoad loaded = CatalogLoad::kError;
    const Result load = load_view_catalog(o.views ? o.views : "", catalog, loaded);
    bool default_cam = false;
    // A scene outside the catalog (or without one) has one view, the default camera: --view 1
    // or --view default names it (names_default_view, as Python's cwbvh.view).
    const bool outside = loaded == CatalogLoad::kAbsent || (loaded == CatalogLoad::kLoaded && !catalog.has_scene(scene));
    if (loaded == CatalogLoad::kError ||
        (loaded == CatalogLoad::kAbsent && o.view && !names_default_view(o.view))) {
        return error(kExitBadInput, (v + ": " + load.message).c_str());
    } else if (loaded == CatalogLoad::kAbsent) {
        default_cam = true;
        note = "default camera (no view catalog: " + load.message + ")";
    } else if (o.view && outside && names_default_view(o.view)) {
        default_cam = true;
        note = "default camera (scene '" + scene + "' not in " + catalog.source() + ")";
    } else if (o.view) {
        View view;
        if (const Result r = catalog.find(scene, o.view, view); !r.ok())
            return error(kExitUsage, (v + ": --view: " + r.message).c_str());
        camera = view.camera;
        note = scene + " " + view.name + " (" + catalog.source() + ":" + std::to_string(view.line) + ")";
    } else if (catalog.has_scene(scene)) {
        const View view = catalog.views_of(scene).front();
        camera = view.camera;
        note = scene + " " + view.name + " (first of " + std::to_string(catalog.views_of(scene).size()) + ", " +
               catalog.source() + ":" + std::to_string(view.line) + ")";
    } else {
        default_cam = true;
        note = "default camera (scene '" + scene + "' not in " + catalog.source() + ")";
    }
    if (default_cam) {
        if (const Result r = scene_camera(b, path, camera); !r.ok()) return error(kExitBadInput, r.message.c_str());
    }
    return 0;
}

}  // namespace cwbvh::tool
