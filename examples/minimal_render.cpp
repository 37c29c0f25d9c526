// minimal_render: load a .cwbvh at start-up, trace one frame of primary rays on the
// GPU (cwbvh/kernels/gpu_trace.h) or, without a usable GPU, on the CPU (cwbvh_cpu_trace),
// shade by |cos| between the view ray and the geometric normal, write a binary PPM.
//
// usage: minimal_render SCENE.cwbvh OUT.ppm [WIDTH HEIGHT] [--cpu]
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cwbvh/format/file_io.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/gpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/kernels/two_level_file.h"
#include "cwbvh/loader/loader.h"

namespace {

int usage(const char* why) {
    std::fprintf(stderr, "minimal_render: %s\nusage: minimal_render SCENE.cwbvh OUT.ppm [WIDTH HEIGHT] [--cpu]\n", why);
    return 2;
}

/// A decimal integer in [1, 16384], nothing else.
bool parse_size(const std::string& text, int& out) {
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
    return ec == std::errc() && end == text.data() + text.size() && out >= 1 && out <= 16384;
}

}  // namespace

int main(int argc, char** argv) {
    using namespace cwbvh;
    int w = 640, h = 480;
    bool force_cpu = false;
    std::vector<std::string> pos;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--cpu") force_cpu = true;
        else if (a.size() > 1 && a[0] == '-') return usage(("unknown option " + a).c_str());
        else pos.push_back(a);
    }
    if (pos.size() != 2 && pos.size() != 4) return usage("expects SCENE.cwbvh OUT.ppm and optionally WIDTH HEIGHT");
    if (pos.size() == 4 && (!parse_size(pos[2], w) || !parse_size(pos[3], h)))
        return usage("WIDTH and HEIGHT must be integers in [1, 16384]");
    // Never the input as the output (the scene is mapped while the image is written).
    const Result out_ok = check_output_path(pos[1], {pos[0]});
    if (!out_ok.ok()) {
        std::fprintf(stderr, "minimal_render: %s\n", out_ok.message.c_str());
        return 2;
    }

    // All sections: a two-level file (format 1.2, instanced glTF) needs MESH/INST/TLAS too.
    Expected<File> file = File::open(pos[0]);
    if (!file.ok()) {
        std::fprintf(stderr, "%s\n", file.error().message.c_str());
        return 1;
    }
    const SceneBounds b = file->bounds() ? *file->bounds() : SceneBounds{{-1, -1, -1}, {1, 1, 1}};

    // Camera: on a diagonal of the bounds, looking at the centre, 50 degree vertical fov.
    float c[3], e[3], diag = 0;
    for (int a = 0; a < 3; ++a) {
        c[a] = 0.5f * (b.lo[a] + b.hi[a]);
        diag += (b.hi[a] - b.lo[a]) * (b.hi[a] - b.lo[a]);
    }
    diag = std::sqrt(diag);
    e[0] = c[0] + 0.55f * diag, e[1] = c[1] + 0.35f * diag, e[2] = c[2] + 0.8f * diag;
    float f[3] = {c[0] - e[0], c[1] - e[1], c[2] - e[2]};
    auto normalize = [](float* v) {
        const float l = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        for (int a = 0; a < 3; ++a) v[a] /= l;
    };
    normalize(f);
    float r[3] = {-f[2], 0.0f, f[0]};
    normalize(r);
    const float u[3] = {r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]};
    const float th = std::tan(25.0f * 3.14159265f / 180.0f), aspect = float(w) / float(h);
    std::vector<Ray> rays(size_t(w) * h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const float px = (2.0f * (x + 0.5f) / w - 1.0f) * th * aspect, py = (1.0f - 2.0f * (y + 0.5f) / h) * th;
            Ray& ray = rays[size_t(y) * w + x];
            for (int a = 0; a < 3; ++a) {
                ray.org[a] = e[a];
                ray.dir[a] = f[a] + px * r[a] + py * u[a];
            }
            ray.tmin = 0.0f;
            ray.tmax = kInfinity;
        }

    std::vector<Hit> hits(rays.size());
    std::vector<uint32_t> instances(rays.size(), kInvalidIndex);  // two-level: the hit's INST index
    TwoLevelScene scene{};
    const bool two_level = two_level_scene(*file, scene);
    std::string why;
    if (!force_cpu && gpu_available(why)) {
        GpuTraceOptions o;
        Expected<GpuTraceResult> traced =
            trace_on_gpu(*file, rays.data(), hits.data(), instances.data(), rays.size(), o);
        if (!traced.ok()) {
            std::fprintf(stderr, "GPU trace failed: %s\n", traced.error().message.c_str());
            return 1;
        }
        const GpuTraceResult& res = traced.value();
        std::printf("GPU (%s): %zu rays, kernel %.3f ms, %.1f Mrays/s\n", res.device_name.c_str(), rays.size(),
                    res.kernel_ms, res.mrays_per_s);
    } else {
        if (!force_cpu) std::printf("no GPU (%s): tracing on the CPU\n", why.c_str());
        const CpuTraceStats s =
            two_level ? trace_two_level_cpu(scene, rays.data(), hits.data(), instances.data(), rays.size())
                      : trace_cwbvh_cpu(file->nodes().data(), file->nodes().size(), file->triangles().data(),
                                        file->triangles().size(), rays.data(), hits.data(), rays.size());
        std::printf("CPU: %zu rays, %.3f s, %.2f Mrays/s\n", rays.size(), s.seconds,
                    s.seconds > 0 ? double(rays.size()) / s.seconds / 1e6 : 0.0);
    }

    // The hit triangle in world space (a two-level hit's triangle moved by its instance).
    const PrimTable table(file->triangles().data(), file->triangles().size());
    std::vector<unsigned char> img(size_t(w) * h * 3);
    for (size_t i = 0; i < hits.size(); ++i) {
        float shade = 0.1f;
        TriangleRecord t{};
        const TriangleRecord* found = hits[i].prim == kMissPrim ? nullptr : table.find(hits[i].prim);
        const bool shaded = found && (!two_level || world_hit_triangle(scene, table, instances[i], hits[i].prim, t));
        if (found && !two_level) t = *found;
        if (shaded) {
            float e1[3], e2[3];
            for (int a = 0; a < 3; ++a) {
                e1[a] = t.v1[a] - t.v0[a];
                e2[a] = t.v2[a] - t.v0[a];
            }
            float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
            float d[3] = {rays[i].dir[0], rays[i].dir[1], rays[i].dir[2]};
            normalize(n);
            normalize(d);
            shade = 0.2f + 0.8f * std::fabs(n[0] * d[0] + n[1] * d[1] + n[2] * d[2]);
            if (!(shade == shade)) shade = 0.2f;
        }
        const unsigned char v = (unsigned char)(std::fmin(shade, 1.0f) * 255.0f);
        img[3 * i] = v;
        img[3 * i + 1] = v;
        img[3 * i + 2] = (unsigned char)(hits[i].prim == kMissPrim ? 60 : v);
    }
    // The image appears whole or not at all (a full disk leaves no partial file).
    std::string ppm = "P6\n" + std::to_string(w) + " " + std::to_string(h) + "\n255\n";
    ppm.append(reinterpret_cast<const char*>(img.data()), img.size());
    if (const Result written = write_file_atomic(pos[1], ppm.data(), ppm.size()); !written.ok()) {
        std::fprintf(stderr, "minimal_render: %s\n", written.message.c_str());
        return 1;
    }
    return 0;
}
