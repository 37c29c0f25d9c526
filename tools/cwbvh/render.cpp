// cwbvh render FILE -o IMAGE.png [--heatmap] [--width W] [--height H] [--view NAME|N]
//                   [--views CATALOG] [--scene KEY] [--camera ex,ey,ez,tx,ty,tz,fov]
//                   [--ao N] [--fast] [--threads N]
// Renders the scene with the CPU reference traversal, from the camera of camera_choice.h
// (by default the scene's first catalog view, inside the enclosed scenes; the default
// camera for a scene not in the catalog). Prints the view used.
//   default   grey headlight shading |cos(geometric normal, ray)|, optionally
//             times ambient occlusion (N any-hit rays per pixel, cosine-weighted,
//             reach 1/8 of the scene diagonal); background is a saturated blue that
//             grey shading never produces, so holes show;
//   --heatmap wide nodes visited per camera ray on a blue-green-yellow-red ramp
//             from the minimum to the maximum count (printed as the legend).
// A two-level file (format 1.2) is traced by traverse_two_level.h; shading and AO
// use each hit's world-space triangle (world_triangle), nodes counted over both levels.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "args.h"
#include "commands.h"
#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/view_catalog.h"
#include "cwbvh/loader/loader.h"
#include "png_write.h"
#include "camera_choice.h"
#include "cwbvh/kernels/two_level_file.h"

namespace cwbvh::tool {
namespace {

constexpr uint8_t kBackground[3] = {25, 60, 160};

/// Piecewise-linear ramp blue -> cyan -> green -> yellow -> red for x in [0, 1].
void ramp(double x, uint8_t* rgb) {
    static const double k[5][3] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
    x = std::clamp(x, 0.0, 1.0) * 4.0;
    const int i = std::min(3, int(x));
    const double f = x - i;
    for (int c = 0; c < 3; ++c) rgb[c] = uint8_t(std::lround(255.0 * (k[i][c] * (1 - f) + k[i + 1][c] * f)));
}

}  // namespace

int run_render(int argc, char** argv) {
    const char* usage =
        "usage: cwbvh render FILE -o IMAGE.png [--heatmap] [--width W] [--height H] [--view NAME|N] "
        "[--views CATALOG] [--scene KEY] [--camera ex,ey,ez,tx,ty,tz,fov] [--ao N] [--fast] [--threads N]";
    const char* path = nullptr;
    const char* out = nullptr;
    CameraOptions cam_opts;
    bool heatmap = false, fast = false;
    uint32_t width = 800, height = 800, ao = 0, threads = 0;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (const int c = cam_opts.parse("render", argc, argv, i); c != 0) {
            if (c < 0) return kExitUsage;
        } else if (a == "--heatmap") {
            heatmap = true;
        } else if (a == "--fast") {
            fast = true;
        } else if (a == "--width") {
            if (!parse_u32(option_value(argc, argv, i), 1, 16384, width))
                return error(kExitUsage, "render: --width needs an integer in [1, 16384]");
        } else if (a == "--height") {
            if (!parse_u32(option_value(argc, argv, i), 1, 16384, height))
                return error(kExitUsage, "render: --height needs an integer in [1, 16384]");
        } else if (a == "--ao") {
            if (!parse_u32(option_value(argc, argv, i), 0, 256, ao))
                return error(kExitUsage, "render: --ao needs an integer in [0, 256]");
        } else if (a == "--threads") {
            if (!parse_u32(option_value(argc, argv, i), 0, 1024, threads))
                return error(kExitUsage, "render: --threads needs an integer in [0, 1024]");
        } else if (a == "-o" || a == "--output") {
            if (!(out = option_value(argc, argv, i))) return error(kExitUsage, "render: -o needs a path");
        } else if (a.size() > 1 && a[0] == '-') {
            return error(kExitUsage, ("render: unknown option " + a).c_str());
        } else if (path) {
            return error(kExitUsage, "render: expects exactly one FILE");
        } else {
            path = argv[i];
        }
    }
    if (!path || !out) return error(kExitUsage, usage);

    if (const Result r = check_output_path(out, cam_opts.inputs(path)); !r.ok())
        return error(kExitBadInput, r.message.c_str());
    auto file = File::open(path, {true, trace_section_mask(kMaskBounds)});
    if (!file.ok()) return error(kExitBadInput, file.error().describe().c_str());
    const SceneBounds& b = *file->bounds();
    Camera cam;
    std::string view_note;
    if (const int rc = choose_camera("render", path, b, cam_opts, cam, view_note); rc != 0) return rc;
    std::printf("view: %s: %s\n", view_note.c_str(), format_camera(cam).c_str());

    const auto nodes = file->nodes();
    const auto tris = file->triangles();
    TwoLevelScene two;
    const bool two_level = two_level_scene(*file, two);
    // One trace call for both kinds of scene; instances[i] is hit i's INST index
    // (two-level only).
    auto trace = [&](const std::vector<Ray>& r, std::vector<Hit>& h, std::vector<uint32_t>& inst,
                     const CpuTraceOptions& o) {
        h.resize(r.size());
        inst.assign(r.size(), kInvalidIndex);
        return two_level ? trace_two_level_cpu(two, r.data(), h.data(), inst.data(), r.size(), o)
                         : trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(), r.data(), h.data(),
                                           r.size(), o);
    };
    const std::vector<Ray> rays = camera_rays(cam, width, height);
    std::vector<Hit> hits;
    std::vector<uint32_t> instances;
    std::vector<TraceCounters> counters(rays.size());
    CpuTraceOptions opt;
    opt.threads = threads;
    opt.test = fast ? TriangleTest::kFast : TriangleTest::kWatertight;
    opt.counters = counters.data();
    const CpuTraceStats s = trace(rays, hits, instances, opt);
    double total_seconds = s.seconds;

    std::vector<uint8_t> rgb(size_t(width) * height * 3);
    if (heatmap) {
        uint32_t lo = 0xFFFFFFFFu, hi = 0;
        for (const TraceCounters& c : counters) {
            lo = std::min(lo, c.nodes);
            hi = std::max(hi, c.nodes);
        }
        for (size_t i = 0; i < rays.size(); ++i)
            ramp(hi > lo ? double(counters[i].nodes - lo) / double(hi - lo) : 0.0, &rgb[i * 3]);
        std::printf("heatmap: wide nodes visited per ray: min %u (blue) .. max %u (red), mean %.2f; "
                    "ramp blue-cyan-green-yellow-red, linear\n",
                    lo, hi, double(s.nodes_visited) / double(std::max<uint64_t>(1, s.rays)));
    } else {
        const PrimTable table(tris.data(), tris.size());
        std::vector<double> shade(rays.size(), -1.0);
        std::vector<Ray> ao_rays;
        std::vector<uint32_t> ao_pixel;
        double diag2 = 0;
        for (int a = 0; a < 3; ++a) diag2 += (double(b.hi[a]) - b.lo[a]) * (double(b.hi[a]) - b.lo[a]);
        const float reach = float(std::sqrt(diag2) / 8.0);
        for (size_t i = 0; i < rays.size(); ++i) {
            if (hits[i].prim == kMissPrim) continue;
            const TriangleRecord* t = table.find(hits[i].prim);
            TriangleRecord world;
            if (two_level) t = world_hit_triangle(two, table, instances[i], hits[i].prim, world) ? &world : nullptr;
            float n[3];
            if (!t || !geometric_normal(*t, n)) {
                shade[i] = 0.5;
                continue;
            }
            const double c = std::fabs(double(n[0]) * rays[i].dir[0] + double(n[1]) * rays[i].dir[1] +
                                       double(n[2]) * rays[i].dir[2]);
            shade[i] = 0.15 + 0.85 * c;
            for (uint32_t k = 0; k < ao; ++k) {
                Ray r;
                if (diffuse_ray(rays[i], hits[i], *t, 7u, uint32_t(i), k + 1, reach, r)) {
                    ao_rays.push_back(r);
                    ao_pixel.push_back(uint32_t(i));
                }
            }
        }
        if (ao > 0) {
            std::vector<Hit> ao_hits;
            std::vector<uint32_t> ao_instances;
            CpuTraceOptions aopt;
            aopt.threads = threads;
            aopt.mode = HitMode::kAny;
            aopt.test = opt.test;
            const CpuTraceStats as = trace(ao_rays, ao_hits, ao_instances, aopt);
            total_seconds += as.seconds;
            std::vector<uint32_t> open(rays.size(), 0);
            for (size_t j = 0; j < ao_rays.size(); ++j)
                if (ao_hits[j].prim == kMissPrim) ++open[ao_pixel[j]];
            for (size_t i = 0; i < rays.size(); ++i)
                if (shade[i] >= 0) shade[i] *= 0.2 + 0.8 * double(open[i]) / ao;
        }
        for (size_t i = 0; i < rays.size(); ++i) {
            if (shade[i] < 0) {
                std::copy(kBackground, kBackground + 3, &rgb[i * 3]);
            } else {
                const uint8_t g = uint8_t(std::lround(255.0 * std::clamp(shade[i], 0.0, 1.0)));
                rgb[i * 3 + 0] = rgb[i * 3 + 1] = rgb[i * 3 + 2] = g;
            }
        }
        std::printf("shaded: %llu of %zu pixels hit; background (holes) is RGB(%u,%u,%u)\n",
                    (unsigned long long)s.hits, rays.size(), kBackground[0], kBackground[1], kBackground[2]);
    }
    std::string err;
    if (!write_png_rgb(out, rgb.data(), width, height, err)) return error(kExitBadInput, err.c_str());
    std::printf("%s: %ux%u%s, trace %.3f s -> %s\n", path, width, height,
                two_level ? (", two-level: " + std::to_string(two.instance_count) + " instances of " +
                             std::to_string(two.mesh_count) + " meshes")
                                .c_str()
                          : "",
                total_seconds, out);
    return kExitOk;
}

}  // namespace cwbvh::tool
