// inline_ao: ambient occlusion from a renderer's own code, with the inline queries of
// cwbvh/kernels/query.h (intersect for the camera ray, occluded for the occlusion rays).
// The shading function ao_pixel (inline_ao.h) is host/device code: on a GPU it runs in
// the example's own kernel (inline_ao_gpu.cu) over DeviceScene::view(); without one, or
// with --cpu, in a loop of host threads over host_view(file). The camera: the scene's first
// view in the view catalog (views/catalog.txt; scene key = the file's stem: inside the
// enclosed scenes), else default_camera of the bounds. Writes a binary PGM.
//
// usage: inline_ao SCENE.cwbvh OUT.pgm [WIDTH HEIGHT] [--samples N] [--cpu]
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/two_level_file.h"
#include "cwbvh/kernels/view_catalog.h"
#include "cwbvh/loader/loader.h"
#include "inline_ao.h"
#if defined(CWBVH_HAVE_CUDA)
#include "cwbvh/kernels/device_scene.h"
#include "inline_ao_gpu.h"
#endif

using namespace cwbvh;
using namespace cwbvh::example;

namespace {

int usage() {
    std::fprintf(stderr, "usage: inline_ao SCENE.cwbvh OUT.pgm [WIDTH HEIGHT] [--samples N] [--cpu]\n"
                         "  WIDTH HEIGHT: integers in [1, 16384]; N: an integer in [1, 4096]\n");
    return 2;
}

/// A decimal integer in [lo, hi], nothing else ("10x", "", "-1" are refused).
bool parse_int(const std::string& text, int lo, int hi, int& out) {
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size() && out >= lo && out <= hi;
}

}  // namespace

int main(int argc, char** argv) {
    int w = 320, h = 240, samples = 16;
    bool force_cpu = false;
    std::vector<std::string> pos;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--cpu") {
            force_cpu = true;
        } else if (a == "--samples" && i + 1 < argc) {
            if (!parse_int(argv[++i], 1, 4096, samples)) return usage();
        } else if (a.size() > 1 && a[0] == '-') {
            return usage();
        } else {
            pos.push_back(a);
        }
    }
    if (pos.size() != 2 && pos.size() != 4) return usage();
    if (pos.size() == 4 && (!parse_int(pos[2], 1, 16384, w) || !parse_int(pos[3], 1, 16384, h))) return usage();

    // Never the input as the output (the scene is mapped while the image is written).
    const Result out_ok = check_output_path(pos[1], {pos[0]});
    if (!out_ok.ok()) {
        std::fprintf(stderr, "inline_ao: %s\n", out_ok.message.c_str());
        return 2;
    }
    Expected<File> file = File::open(pos[0]);
    if (!file.ok()) {
        std::fprintf(stderr, "inline_ao: %s\n", file.error().message.c_str());
        return 1;
    }
    const SceneBounds b = file->bounds() ? *file->bounds() : SceneBounds{{-1, -1, -1}, {1, 1, 1}};
    // The camera rays (host code of the library: ray_gen.h, view_catalog.h).
    ViewCatalog catalog;
    CatalogLoad loaded = CatalogLoad::kAbsent;
    const Result cat = load_view_catalog("", catalog, loaded);
    if (loaded == CatalogLoad::kError) {
        std::fprintf(stderr, "inline_ao: %s\n", cat.message.c_str());
        return 1;
    }
    const View view = benchmark_views(catalog, scene_key(pos[0]), b).front();
    std::printf("view: %s %s (%s)\n", scene_key(pos[0]).c_str(), view.name.c_str(), format_camera(view.camera).c_str());
    const std::vector<Ray> rays = camera_rays(view.camera, uint32_t(w), uint32_t(h));
    float diag = 0.0f;
    for (int a = 0; a < 3; ++a) diag += (b.hi[a] - b.lo[a]) * (b.hi[a] - b.lo[a]);
    diag = std::sqrt(diag);
    const AoParams params{samples, 0.05f * diag};
    std::vector<float> ao(rays.size());

    std::string why;
    bool on_gpu = false;
#if defined(CWBVH_HAVE_CUDA)
    if (!force_cpu && gpu_available(why)) {
        Expected<DeviceScene> ds = DeviceScene::upload(*file);
        if (!ds.ok()) {
            std::fprintf(stderr, "inline_ao: %s\n", ds.error().message.c_str());
            return 1;
        }
        float ms = 0.0f;
        std::string error;
        if (!render_ao_gpu(ds->view(), params, rays, ao, ms, error)) {
            std::fprintf(stderr, "inline_ao: %s: GPU: %s\n", pos[0].c_str(), error.c_str());
            return 1;
        }
        on_gpu = true;
        std::printf("GPU: %dx%d pixels, %d occlusion rays each: kernel %.3f ms\n", w, h, samples, double(ms));
    }
#else
    why = "built without CUDA";
#endif
    if (!on_gpu) {
        if (!force_cpu) std::printf("no GPU (%s): shading on the CPU\n", why.c_str());
        const SceneView scene = host_view(*file);  // the same function, host pointers
        const auto t0 = std::chrono::steady_clock::now();
        const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
        std::vector<std::thread> pool;
        for (unsigned t = 0; t < threads; ++t)
            pool.emplace_back([&, t] {
                for (size_t i = t; i < rays.size(); i += threads) ao[i] = ao_pixel(scene, params, rays[i], uint32_t(i));
            });
        for (std::thread& th : pool) th.join();
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        std::printf("CPU: %dx%d pixels, %d occlusion rays each: %.3f s (%u threads)\n", w, h, samples, s, threads);
    }

    // Grey levels: background 40, geometry 60 + 195 * unoccluded share.
    std::vector<unsigned char> img(ao.size());
    size_t hit = 0;
    double sum = 0.0;
    for (size_t i = 0; i < ao.size(); ++i) {
        if (ao[i] < 0.0f) {
            img[i] = 40;
            continue;
        }
        ++hit;
        sum += ao[i];
        img[i] = (unsigned char)(60.0f + 195.0f * ao[i]);
    }
    // The image appears whole or not at all (a full disk leaves no partial file).
    std::string pgm = "P5\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n";
    pgm.append(reinterpret_cast<const char*>(img.data()), img.size());
    if (const Result r = write_file_atomic(pos[1], pgm.data(), pgm.size()); !r.ok()) {
        std::fprintf(stderr, "inline_ao: %s\n", r.message.c_str());
        return 1;
    }
    std::printf("%s: %zu of %zu pixels on geometry, mean unoccluded share %.3f\n", pos[1].c_str(), hit, ao.size(),
                hit ? sum / double(hit) : 0.0);
    return 0;
}
