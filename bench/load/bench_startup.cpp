// Start-up time, process start to first ray: a renderer that maps a compiled
// .cwbvh (open + validate + checksums of NODE/TRIS/BNDS, then one traced ray)
// versus one that imports the source mesh and builds an Embree scene
// (rtcCommitScene at MEDIUM or HIGH, default device = all cores) and traces one
// ray with rtcIntersect1.
//
//   cwbvh_bench_startup cwbvh FILE.cwbvh            (one child run)
//   cwbvh_bench_startup embree MESH medium|high     (one child run)
//   cwbvh_bench_startup measure [--repeats R] -- cwbvh FILE | embree MESH Q
//
// `measure` fork/execs this executable (/proc/self/exe) with the child
// arguments R times and reports the wall time from just before fork() to
// waitpid() (so exec, dynamic linking, static initialisers and exit count):
// one JSON object with the median and every run. The page cache is warm after
// the first run (the median is a warm-cache figure).
#include <embree3/rtcore.h>
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cwbvh/compiler/import.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"

namespace {
[[noreturn]] void die(const std::string& m) {
    std::fprintf(stderr, "cwbvh_bench_startup: %s\n", m.c_str());
    std::exit(2);
}

// The centre ray of the default camera (ray_gen.h) for the given bounds.
cwbvh::Ray first_ray(const cwbvh::SceneBounds& b) {
    return cwbvh::camera_rays(cwbvh::default_camera(b), 1, 1)[0];
}

int run_cwbvh(const std::string& path) {
    cwbvh::OpenOptions o;
    o.sections = cwbvh::kMaskNodes | cwbvh::kMaskTriangles | cwbvh::kMaskBounds;
    auto f = cwbvh::File::open(path, o);
    if (!f.ok()) die(f.error().message);
    const cwbvh::Ray r = first_ray(*f->bounds());
    cwbvh::Hit h;
    cwbvh::CpuTraceOptions to;
    to.threads = 1;
    cwbvh::trace_cwbvh_cpu(f->nodes().data(), f->nodes().size(), f->triangles().data(), f->triangles().size(), &r,
                           &h, 1, to);
    std::printf("t=%.9g prim=%u\n", h.t, h.prim);
    return 0;
}

int run_embree(const std::string& mesh, const std::string& quality) {
    cwbvh::compiler::Scene scene;
    std::vector<std::string> warnings;
    if (const cwbvh::Result r = cwbvh::compiler::import_scene({mesh}, {}, scene, warnings); !r.ok()) die(r.message);
    cwbvh::SceneBounds b{{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
    for (const auto& v : scene.vertices)
        for (int a = 0; a < 3; ++a) {
            b.lo[a] = std::min(b.lo[a], v[a]);
            b.hi[a] = std::max(b.hi[a], v[a]);
        }
    RTCDevice dev = rtcNewDevice(nullptr);
    RTCScene s = rtcNewScene(dev);
    const RTCBuildQuality q = quality == "high" ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM;
    rtcSetSceneBuildQuality(s, q);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(g, q);
    // Embree may read 16 bytes at the last vertex: shared buffers need 4 bytes of padding.
    scene.vertices.reserve(scene.vertices.size() + 1);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, scene.vertices.data(), 0,
                               3 * sizeof(float), scene.vertices.size());
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, scene.indices.data(), 0,
                               3 * sizeof(uint32_t), scene.indices.size());
    rtcCommitGeometry(g);
    rtcAttachGeometry(s, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(s);
    const cwbvh::Ray r = first_ray(b);
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    RTCRayHit rh{};
    rh.ray.org_x = r.org[0], rh.ray.org_y = r.org[1], rh.ray.org_z = r.org[2];
    rh.ray.dir_x = r.dir[0], rh.ray.dir_y = r.dir[1], rh.ray.dir_z = r.dir[2];
    rh.ray.tnear = r.tmin;
    rh.ray.tfar = r.tmax;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(s, &ctx, &rh);
    std::printf("t=%.9g prim=%u\n", rh.ray.tfar, rh.hit.primID);
    rtcReleaseScene(s);
    rtcReleaseDevice(dev);
    return 0;
}

double now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

int measure(int argc, char** argv) {
    int repeats = 5, i = 2;
    for (; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--repeats" && i + 1 < argc) repeats = std::atoi(argv[++i]);
        else if (a == "--") { ++i; break; }
        else die("measure: unknown option " + a);
    }
    if (i >= argc || repeats < 1) die("measure: usage: measure [--repeats R] -- <child args>");
    std::vector<char*> args{argv[0]};
    for (int k = i; k < argc; ++k) args.push_back(argv[k]);
    args.push_back(nullptr);
    std::vector<double> t;
    for (int r = 0; r < repeats; ++r) {
        const double t0 = now();
        const pid_t pid = fork();
        if (pid < 0) die("fork failed");
        if (pid == 0) {
            const int fd = open("/dev/null", O_WRONLY);
            if (fd >= 0) dup2(fd, 1);
            execv("/proc/self/exe", args.data());
            _exit(127);
        }
        int st = 0;
        if (waitpid(pid, &st, 0) != pid || !WIFEXITED(st) || WEXITSTATUS(st) != 0) die("child run failed");
        t.push_back(now() - t0);
    }
    std::vector<double> s = t;
    std::sort(s.begin(), s.end());
    const double med = s.size() % 2 ? s[s.size() / 2] : 0.5 * (s[s.size() / 2 - 1] + s[s.size() / 2]);
    std::printf("{\"variant\": \"%s\", \"input\": \"%s\", \"quality\": \"%s\", \"repeats\": %d, \"seconds\": %.6f, "
                "\"seconds_all\": [",
                argv[i], i + 1 < argc ? argv[i + 1] : "", i + 2 < argc ? argv[i + 2] : "", repeats, med);
    for (size_t k = 0; k < t.size(); ++k) std::printf("%s%.6f", k ? ", " : "", t[k]);
    std::printf("]}\n");
    return 0;
}
}  // namespace

int main(int argc, char** argv) {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "cwbvh" && argc == 3) return run_cwbvh(argv[2]);
    if (mode == "embree" && argc == 4 && (std::string(argv[3]) == "medium" || std::string(argv[3]) == "high"))
        return run_embree(argv[2], argv[3]);
    if (mode == "measure") return measure(argc, argv);
    die("usage: cwbvh FILE | embree MESH medium|high | measure [--repeats R] -- <child args>");
}
