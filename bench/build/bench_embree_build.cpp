// Embree 3 scene build time on the triangles of a .cwbvh file written with
// --keep-mesh (VERT/INDX): rtcCommitScene at RTC_BUILD_QUALITY_MEDIUM or HIGH,
// with a device limited to N threads. Prints one JSON object on stdout.
//
//   cwbvh_bench_embree_build FILE.cwbvh [--quality medium|high] [--threads N] [--repeats R]
//
// Timed: rtcNewScene + geometry setup (vertex/index copy into Embree buffers) +
// rtcCommitScene, per repeat; the device is created once (thread pool start-up
// is not counted). commit_seconds is rtcCommitScene alone.
#include <embree3/rtcore.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "cwbvh/loader/loader.h"

namespace {
double now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}
double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n == 0 ? 0.0 : (n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]));
}
[[noreturn]] void die(const std::string& m) {
    std::fprintf(stderr, "cwbvh_bench_embree_build: %s\n", m.c_str());
    std::exit(2);
}
}  // namespace

int main(int argc, char** argv) {
    std::string path, quality = "medium";
    int threads = 1, repeats = 3;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) die("missing value after " + a);
            return argv[++i];
        };
        if (a == "--quality") quality = next();
        else if (a == "--threads") threads = std::atoi(next().c_str());
        else if (a == "--repeats") repeats = std::atoi(next().c_str());
        else if (!a.empty() && a[0] == '-') die("unknown option " + a);
        else path = a;
    }
    if (path.empty() || threads < 1 || repeats < 1 || (quality != "medium" && quality != "high"))
        die("usage: FILE.cwbvh [--quality medium|high] [--threads N] [--repeats R]");

    cwbvh::OpenOptions oo;
    auto file = cwbvh::File::open(path, oo);
    if (!file.ok()) die(file.error().message);
    const auto verts = file->vertices();
    const auto idx = file->indices();
    if (verts.empty() || idx.empty()) die(path + ": no VERT/INDX sections (compile with --keep-mesh)");
    const size_t nv = verts.size() / 3, nt = idx.size() / 3;

    const std::string cfg = "threads=" + std::to_string(threads);
    RTCDevice dev = rtcNewDevice(cfg.c_str());
    if (!dev) die("rtcNewDevice failed");
    const RTCBuildQuality q = quality == "high" ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM;

    std::vector<double> total, commit;
    for (int r = 0; r < repeats; ++r) {
        const double t0 = now();
        RTCScene scene = rtcNewScene(dev);
        rtcSetSceneBuildQuality(scene, q);
        RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
        rtcSetGeometryBuildQuality(g, q);
        // Embree reads 16 bytes per vertex: the buffer layout is 12-byte stride, padded by Embree.
        float* vb = static_cast<float*>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
        std::memcpy(vb, verts.data(), nv * 3 * sizeof(float));
        uint32_t* ib = static_cast<uint32_t*>(
            rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), nt));
        std::memcpy(ib, idx.data(), nt * 3 * sizeof(uint32_t));
        rtcCommitGeometry(g);
        rtcAttachGeometry(scene, g);
        rtcReleaseGeometry(g);
        const double t1 = now();
        rtcCommitScene(scene);
        const double t2 = now();
        if (rtcGetDeviceError(dev) != RTC_ERROR_NONE) die("embree error during build");
        total.push_back(t2 - t0);
        commit.push_back(t2 - t1);
        rtcReleaseScene(scene);
    }
    rtcReleaseDevice(dev);
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    std::printf("{\"file\": \"%s\", \"triangles\": %zu, \"vertices\": %zu, \"quality\": \"%s\", \"threads\": %d, "
                "\"repeats\": %d, \"seconds\": %.6f, \"commit_seconds\": %.6f, \"seconds_all\": [",
                path.c_str(), nt, nv, quality.c_str(), threads, repeats, median(total), median(commit));
    for (size_t i = 0; i < total.size(); ++i) std::printf("%s%.6f", i ? ", " : "", total[i]);
    std::printf("], \"peak_rss_bytes\": %lld}\n", static_cast<long long>(ru.ru_maxrss) * 1024);
    return 0;
}
