// cwbvh_bench_load [FILE] [--triangles N]: writes a ~100 MB valid synthetic
// file (unless FILE exists), then measures open + validate throughput with and
// without payload checksums, through mmap (File::open) and on a buffer, next
// to a memcpy of the same bytes. Reports the best of several runs in GB/s
// (10^9 bytes per second).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/format/checksum.h"
#include "cwbvh/loader/loader.h"

namespace {

double best_seconds(int runs, const std::function<void()>& fn) {
    double best = 1e30;
    for (int i = 0; i < runs; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        fn();
        best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    return best;
}

}  // namespace

int main(int argc, char** argv) {
    std::string path = (std::filesystem::temp_directory_path() / "cwbvh_bench_load.cwbvh").string();
    uint32_t triangles = 520000;
    for (int i = 1; i < argc; ++i) {
        if (std::strcmp(argv[i], "--triangles") == 0 && i + 1 < argc)
            triangles = uint32_t(std::stoul(argv[++i]));
        else
            path = argv[i];
    }
    if (!std::filesystem::exists(path)) {
        cwbvh::SyntheticOptions o;
        o.triangles = triangles;
        const cwbvh::SceneData scene = cwbvh::make_synthetic_scene(o);
        cwbvh::Writer w;
        cwbvh::add_scene_sections(w, scene);
        if (const cwbvh::Result r = w.write_file(path); !r.ok()) {
            std::fprintf(stderr, "cwbvh_bench_load: error: %s\n", r.describe().c_str());
            return 1;
        }
    }
    const double bytes = double(std::filesystem::file_size(path));
    std::printf("file %s: %.1f MB\n", path.c_str(), bytes / 1e6);

    auto open_with = [&](bool checksums) {
        cwbvh::OpenOptions o;
        o.verify_checksums = checksums;
        auto f = cwbvh::File::open(path, o);
        if (!f.ok()) {
            std::fprintf(stderr, "cwbvh_bench_load: error: %s\n", f.error().describe().c_str());
            std::exit(1);
        }
    };
    open_with(true);  // warm the page cache

    const size_t size = size_t(bytes);
    std::vector<uint8_t> buffer(size), copy(size);
    {
        FILE* f = std::fopen(path.c_str(), "rb");
        if (f == nullptr || std::fread(buffer.data(), 1, buffer.size(), f) != buffer.size()) return 1;
        std::fclose(f);
    }
    const int runs = 5;
    const double t_memcpy = best_seconds(runs, [&] { std::memcpy(copy.data(), buffer.data(), buffer.size()); });
    volatile uint64_t sink = 0;
    const double t_xxh3 = best_seconds(runs, [&] { sink = cwbvh::payload_checksum(buffer.data(), buffer.size()); });
    auto validate_buffer = [&](bool checksums) {
        cwbvh::ValidateOptions o;
        o.verify_checksums = checksums;
        if (!cwbvh::validate(buffer, o).ok()) std::exit(1);
    };
    const double t_buf_sum = best_seconds(runs, [&] { validate_buffer(true); });
    const double t_buf_nosum = best_seconds(runs, [&] { validate_buffer(false); });
    const double t_map_sum = best_seconds(runs, [&] { open_with(true); });
    const double t_map_nosum = best_seconds(runs, [&] { open_with(false); });
    cwbvh::OpenOptions render;
    render.sections = cwbvh::kMaskNodes | cwbvh::kMaskTriangles;
    render.verify_checksums = false;
    const double t_render = best_seconds(runs, [&] {
        if (!cwbvh::File::open(path, render).ok()) std::exit(1);
    });

    auto row = [&](const char* what, double t) { std::printf("  %-44s %7.2f GB/s  (%.1f ms)\n", what, bytes / t / 1e9, t * 1e3); };
    std::printf("best of %d runs:\n", runs);
    row("memcpy (baseline)", t_memcpy);
    row("XXH3-64 of the whole file", t_xxh3);
    row("validate buffer, checksums", t_buf_sum);
    row("validate buffer, no checksums", t_buf_nosum);
    row("File::open (mmap) + validate, checksums", t_map_sum);
    row("File::open (mmap) + validate, no checksums", t_map_nosum);
    row("File::open NODE+TRIS only, no checksums", t_render);
    return 0;
}
