// cwbvh rays FILE --primary|--diffuse [--bounce N] [--width W] [--height H]
//                 [--seed S] [--view NAME|N] [--views CATALOG] [--scene KEY]
//                 [--camera ex,ey,ez,tx,ty,tz,fov] [--threads N] -o RAYS
// Writes a ray file (spec/rays.md): camera rays, or the diffuse rays of bounce N
// (the paper's "diffuse" benchmark rays), from the camera of camera_choice.h (--camera,
// --view, --views, --scene; by default the scene's first catalog view). Prints the view used.
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
#include "camera_choice.h"
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
    CameraOptions cam_opts;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const char* v = nullptr;
        auto need = [&](uint32_t lo, uint32_t hi, uint32_t& dst) {
            v = option_value(argc, argv, i);
            return parse_u32(v, lo, hi, dst);
        };
        if (const int c = cam_opts.parse("rays", argc, argv, i); c != 0) {
            if (c < 0) return kExitUsage;
        } else if (a == "--primary") {
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
    if (const Result r = check_output_path(out, cam_opts.inputs(path)); !r.ok())
        return error(kExitBadInput, r.message.c_str());
    auto file = File::open(path, {true, trace_section_mask(kMaskBounds)});
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    Camera cam;
    std::string view_note;
    if (const int rc = choose_camera("rays", path, *file->bounds(), cam_opts, cam, view_note); rc != 0) return rc;
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
