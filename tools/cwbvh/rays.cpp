// cwbvh rays FILE --primary|--diffuse [--bounce N] [--width W] [--height H]
//                 [--seed S] [--camera ex,ey,ez,tx,ty,tz,fov] [--threads N] -o RAYS
// Writes a ray file (spec/rays.md): camera rays of the default (or given) camera,
// or the diffuse rays of bounce N (the paper's "diffuse" benchmark rays).
#include <cstdio>
#include <cstring>
#include <string>

#include "args.h"
#include "commands.h"
#include "cwbvh/loader.h"
#include "cwbvh/ray_file.h"
#include "cwbvh/ray_gen.h"

namespace cwbvh::tool {

int run_rays(int argc, char** argv) {
    const char* usage =
        "usage: cwbvh rays FILE --primary|--diffuse [--bounce N] [--width W] [--height H] [--seed S] "
        "[--camera ex,ey,ez,tx,ty,tz,fov] [--threads N] -o RAYS";
    const char* path = nullptr;
    const char* out = nullptr;
    int kind = 0;  // 1 primary, 2 diffuse
    uint32_t bounce = 1, width = 1024, height = 1024, seed = 1, threads = 0;
    const char* camera_text = nullptr;
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

    auto file = File::open(path, {true, kMaskNodes | kMaskTriangles | kMaskBounds});
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    Camera cam = default_camera(*file->bounds());
    std::string err;
    if (camera_text && !parse_camera(camera_text, cam, err)) return error(kExitUsage, ("rays: " + err).c_str());

    std::vector<Ray> rays = camera_rays(cam, width, height);
    if (kind == 2) {
        const auto nodes = file->nodes();
        const auto tris = file->triangles();
        DiffuseRays d = diffuse_rays(nodes.data(), nodes.size(), tris.data(), tris.size(), rays, bounce, seed, threads);
        rays = std::move(d.rays);
    }
    if (!write_ray_file(out, rays.data(), rays.size(), err)) return error(kExitBadInput, err.c_str());
    std::printf("%s: %zu %s rays (%ux%u%s, seed %u) -> %s\n", path, rays.size(), kind == 1 ? "primary" : "diffuse",
                width, height, kind == 2 ? (", bounce " + std::to_string(bounce)).c_str() : "", seed, out);
    return kExitOk;
}

}  // namespace cwbvh::tool
