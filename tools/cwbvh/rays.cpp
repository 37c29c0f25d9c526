// cwbvh rays FILE --primary|--diffuse [--bounce N] [--width W] [--height H]
//                 [--seed S] [--view NAME|N] [--views CATALOG] [--scene KEY]
//                 [--camera ex,ey,ez,tx,ty,tz,fov] [--threads N] -o RAYS
// Writes a ray file (spec/rays.md): camera rays, or the diffuse rays of bounce N
// (the paper's "diffuse" benchmark rays). The camera: --camera when given; else
// view NAME (or the N-th, 1-based) of the scene in the view catalog
// (view_catalog.h: --views, else $CWBVH_VIEWS, else the compiled-in views/catalog.txt);
// else the scene's first catalog view; else, for a scene not in the catalog,
// default_camera. The scene key is FILE's stem unless --scene gives it. Prints the
// view used. A bad --view is a usage error (exit 2); an unreadable or malformed
// catalog is bad input (exit 1), except that a missing compiled-in catalog (neither
// --views nor $CWBVH_VIEWS given) without --view falls back to the default camera.
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "args.h"
#include "commands.h"
#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/ray_file.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/view_catalog.h"
#include "cwbvh/loader/loader.h"
#include "scene_camera.h"
#include "cwbvh/kernels/two_level_file.h"

namespace cwbvh::tool {

int run_rays(int argc, char** argv) {
    const char* usage =
        "usage: cwbvh rays FILE --primary|--diffuse [--bounce N] [--width W] [--height H] [--seed S] "
        "[--view NAME|N] [--views CATALOG] [--scene KEY] [--camera ex,ey,ez,tx,ty,tz,fov] [--threads N] -o RAYS";
    const char* path = nullptr;
    const char* out = nullptr;
    int kind = 0;  // 1 primary, 2 diffuse
    uint32_t bounce = 1, width = 1024, height = 1024, seed = 1, threads = 0;
    const char* camera_text = nullptr;
    const char* view_text = nullptr;
    const char* views_path = nullptr;
    const char* scene_text = nullptr;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const char* v = nullptr;
        auto need = [&](uint32_t lo, uint32_t hi, uint32_t& dst) {
            v = option_value(argc, argv, i);
            return parse_u32(v, lo, hi, dst);
        };
        if (a == "--primary") {
            kind = 1;
        } else if (a == "--diffuse") {
            kind = 2;
        } else if (a == "--bounce") {
            if (!need(1, 64, bounce)) return error(kExitUsage, "rays: --bounce needs an integer in [1, 64]");
        } else if (a == "--width") {
            if (!need(1, 16384, width)) return error(kExitUsage, "rays: --width needs an integer in [1, 16384]");
        } else if (a == "--height") {
            if (!need(1, 16384, height)) return error(kExitUsage, "rays: --height needs an integer in [1, 16384]");
        } else if (a == "--seed") {
            if (!need(0, 0xFFFFFFFFu, seed)) return error(kExitUsage, "rays: --seed needs an unsigned 32-bit integer");
        } else if (a == "--threads") {
            if (!need(0, 1024, threads)) return error(kExitUsage, "rays: --threads needs an integer in [0, 1024]");
        } else if (a == "--camera") {
            camera_text = option_value(argc, argv, i);
            if (!camera_text) return error(kExitUsage, "rays: --camera needs a value");
        } else if (a == "--view") {
            view_text = option_value(argc, argv, i);
            if (!view_text || !*view_text)
                return error(kExitUsage, "rays: --view needs a view name or a 1-based index");
        } else if (a == "--views") {
            views_path = option_value(argc, argv, i);
            if (!views_path || !*views_path) return error(kExitUsage, "rays: --views needs a catalog path");
        } else if (a == "--scene") {
            scene_text = option_value(argc, argv, i);
            if (!scene_text || !*scene_text) return error(kExitUsage, "rays: --scene needs a scene key");
        } else if (a == "-o" || a == "--output") {
            out = option_value(argc, argv, i);
            if (!out) return error(kExitUsage, "rays: -o needs a path");
        } else if (a.size() > 1 && a[0] == '-') {
            return error(kExitUsage, ("rays: unknown option " + a).c_str());
        } else if (path) {
            return error(kExitUsage, "rays: expects exactly one FILE");
        } else {
            path = argv[i];
        }
    }
    if (!path || !out || kind == 0) return error(kExitUsage, usage);
    if (camera_text && view_text) return error(kExitUsage, "rays: --camera and --view exclude each other");

    // The catalog is an input too (--views, $CWBVH_VIEWS or the compiled-in one).
    const std::vector<std::string> inputs{path, views_path ? std::string(views_path) : default_view_catalog_path()};
    if (const Result r = check_output_path(out, inputs); !r.ok()) return error(kExitBadInput, r.message.c_str());
    auto file = File::open(path, {true, trace_section_mask(kMaskBounds)});
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    Camera cam;
    bool default_cam = false;
    std::string view_note;
    const std::string scene = scene_text ? scene_text : scene_key(path);
    if (camera_text) {
        if (const Result r = parse_camera(camera_text, cam); !r.ok())
            return error(kExitUsage, ("rays: " + r.message).c_str());
        view_note = "--camera";
    } else {
        ViewCatalog catalog;
        CatalogLoad loaded = CatalogLoad::kError;
        const Result load = load_view_catalog(views_path ? views_path : "", catalog, loaded);
        const std::string& err = load.message;
        if (loaded == CatalogLoad::kError || (loaded == CatalogLoad::kAbsent && view_text)) {
            return error(kExitBadInput, ("rays: " + err).c_str());
        } else if (loaded == CatalogLoad::kAbsent) {
            default_cam = true;
            view_note = "default camera (no view catalog: " + err + ")";
        } else if (view_text) {
            View v;
            if (const Result r = catalog.find(scene, view_text, v); !r.ok())
                return error(kExitUsage, ("rays: --view: " + r.message).c_str());
            cam = v.camera;
            view_note = scene + " " + v.name + " (" + catalog.source() + ":" + std::to_string(v.line) + ")";
        } else if (catalog.has_scene(scene)) {
            const View v = catalog.views_of(scene).front();
            cam = v.camera;
            view_note = scene + " " + v.name + " (first of " + std::to_string(catalog.views_of(scene).size()) +
                        ", " + catalog.source() + ":" + std::to_string(v.line) + ")";
        } else {
            default_cam = true;
            view_note = "default camera (scene '" + scene + "' not in " + catalog.source() + ")";
        }
    }
    if (default_cam) {
        if (const Result r = scene_camera(*file->bounds(), path, cam); !r.ok())
            return error(kExitBadInput, r.message.c_str());
    }
    std::printf("view: %s: %s\n", view_note.c_str(), format_camera(cam).c_str());

    std::vector<Ray> rays = camera_rays(cam, width, height);
    if (kind == 2) {
        // A two-level scene bounces off the world-space triangle of each hit
        // (world_triangle: the instance's object_to_world applied to its vertices).
        TwoLevelScene two;
        const auto nodes = file->nodes();
        const auto tris = file->triangles();
        DiffuseRays d = two_level_scene(*file, two)
                            ? diffuse_rays(two, rays, bounce, seed, threads)
                            : diffuse_rays(nodes.data(), nodes.size(), tris.data(), tris.size(), rays, bounce, seed,
                                           threads);
        rays = std::move(d.rays);
    }
    if (const Result r = write_ray_file(out, rays.data(), rays.size()); !r.ok())
        return error(kExitBadInput, r.message.c_str());
    std::printf("%s: %zu %s rays (%ux%u%s, seed %u) -> %s\n", path, rays.size(), kind == 1 ? "primary" : "diffuse",
                width, height, kind == 2 ? (", bounce " + std::to_string(bounce)).c_str() : "", seed, out);
    return kExitOk;
}

}  // namespace cwbvh::tool
