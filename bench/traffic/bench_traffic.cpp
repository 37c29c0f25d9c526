// Traversal traffic per ray: nodes visited, triangles tested and the bytes of
// node and triangle data they fetch, CWBVH versus the BVH2 of the same SBVH
// (the file's optional BVH2 section: compile with --keep-sbvh).
//
//   cwbvh_bench_traffic FILE.cwbvh [--width W] [--height H] [--bounces B] [--threads T]
//                       [--camera ex,ey,ez,tx,ty,tz,fov]
//
// Rays: kernels' ray_gen.h: primary rays (W x H) of --camera (bench/run.py passes the
// scene's first view of views/catalog.txt) or default_camera(bounds), and
// the diffuse rays of bounce 1..B (cosine hemisphere at the hit points,
// Wächter-Binder origin offset). Bytes: a visited node is one full node fetch
// (CWBVH 80 B, BVH2 64 B: Bvh2Node holds both child boxes), a tested triangle
// one TriangleRecord (40 bytes). This is the data a traversal touches, not DRAM
// traffic (no cache model). Prints one JSON object.
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"

namespace {
[[noreturn]] void die(const std::string& m) {
    std::fprintf(stderr, "cwbvh_bench_traffic: %s\n", m.c_str());
    std::exit(2);
}
constexpr double kCwbvhNodeBytes = 80, kBvh2NodeBytes = 64, kTriBytes = double(sizeof(cwbvh::TriangleRecord));

struct Row {
    std::string rays, mode, tree;
    size_t count = 0, hits = 0;
    double nodes = 0, tris = 0, node_bytes = 0, tri_bytes = 0, seconds = 0;
    size_t max_nodes = 0;
};
}  // namespace

int main(int argc, char** argv) {
    std::string path;
    uint32_t width = 256, height = 256, bounces = 1;
    unsigned threads = 1;
    std::string camera_text;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) die("missing value after " + a);
            return argv[++i];
        };
        if (a == "--width") width = std::atoi(next().c_str());
        else if (a == "--height") height = std::atoi(next().c_str());
        else if (a == "--bounces") bounces = std::atoi(next().c_str());
        else if (a == "--threads") threads = std::atoi(next().c_str());
        else if (a == "--camera") camera_text = next();
        else if (!a.empty() && a[0] == '-') die("unknown option " + a);
        else path = a;
    }
    if (path.empty() || width == 0 || height == 0 || bounces == 0)
        die("usage: FILE.cwbvh [--width W] [--height H] [--bounces B]");
    auto file = cwbvh::File::open(path);
    if (!file.ok()) die(file.error().message);
    const auto nodes = file->nodes();
    const auto tris = file->triangles();
    const auto bvh2 = file->bvh2();
    const cwbvh::SceneBounds* b = file->bounds();
    if (bvh2.empty()) die(path + ": no BVH2 section (compile with --keep-sbvh)");
    if (!b) die(path + ": no bounds section");

    cwbvh::Camera camera = cwbvh::default_camera(*b);
    if (!camera_text.empty()) {
        if (const cwbvh::Result r = cwbvh::parse_camera(camera_text, camera); !r.ok()) die(r.message);
    }
    const std::vector<cwbvh::Ray> primary = cwbvh::camera_rays(camera, width, height);
    const cwbvh::DiffuseRays diffuse =
        cwbvh::diffuse_rays(nodes.data(), nodes.size(), tris.data(), tris.size(), primary, bounces, 1u, threads);

    std::vector<Row> rows;
    size_t disagreements[2][2] = {};
    for (int set = 0; set < 2; ++set) {
        const std::vector<cwbvh::Ray>& rays = set == 0 ? primary : diffuse.rays;
        for (int m = 0; m < 2; ++m) {
            std::vector<cwbvh::Hit> hits_cw(rays.size()), hits_b2(rays.size());
            for (int tree = 0; tree < 2; ++tree) {
                std::vector<cwbvh::TraceCounters> c(rays.size());
                cwbvh::CpuTraceOptions o;
                o.mode = m == 0 ? cwbvh::HitMode::kClosest : cwbvh::HitMode::kAny;
                o.threads = threads;
                o.counters = c.data();
                const cwbvh::CpuTraceStats s =
                    tree == 0 ? cwbvh::trace_cwbvh_cpu(nodes.data(), nodes.size(), tris.data(), tris.size(),
                                                       rays.data(), hits_cw.data(), rays.size(), o)
                              : cwbvh::trace_bvh2_cpu(bvh2.data(), bvh2.size(), tris.data(), tris.size(), rays.data(),
                                                      hits_b2.data(), rays.size(), o);
                Row r;
                r.rays = set == 0 ? "primary" : "diffuse";
                r.mode = m == 0 ? "closest" : "any";
                r.tree = tree == 0 ? "cwbvh" : "bvh2";
                r.count = rays.size();
                r.hits = s.hits;
                r.seconds = s.seconds;
                for (const auto& x : c) {
                    r.nodes += x.nodes;
                    r.tris += x.triangles;
                    if (x.nodes > r.max_nodes) r.max_nodes = x.nodes;
                }
                const double n = rays.empty() ? 1.0 : double(rays.size());
                r.nodes /= n;
                r.tris /= n;
                r.node_bytes = r.nodes * (tree == 0 ? kCwbvhNodeBytes : kBvh2NodeBytes);
                r.tri_bytes = r.tris * kTriBytes;
                rows.push_back(r);
            }
            for (size_t i = 0; i < rays.size(); ++i) {
                const bool h0 = hits_cw[i].prim != cwbvh::kMissPrim, h1 = hits_b2[i].prim != cwbvh::kMissPrim;
                if (h0 != h1 || (m == 0 && h0 && hits_cw[i].t != hits_b2[i].t)) ++disagreements[set][m];
            }
        }
    }
    std::printf("{\"file\": \"%s\", \"width\": %u, \"height\": %u, \"bounces\": %u, \"cwbvh_nodes\": %zu, "
                "\"bvh2_nodes\": %zu, \"tris\": %zu, \"node_bytes\": {\"cwbvh\": %g, \"bvh2\": %g}, \"tri_bytes\": %g, "
                "\"disagreements\": {\"primary_closest\": %zu, \"primary_any\": %zu, \"diffuse_closest\": %zu, "
                "\"diffuse_any\": %zu},\n \"rows\": [",
                path.c_str(), width, height, bounces, nodes.size(), bvh2.size(), tris.size(), kCwbvhNodeBytes,
                kBvh2NodeBytes, kTriBytes, disagreements[0][0], disagreements[0][1], disagreements[1][0],
                disagreements[1][1]);
    for (size_t i = 0; i < rows.size(); ++i) {
        const Row& r = rows[i];
        std::printf("%s\n  {\"rays\": \"%s\", \"mode\": \"%s\", \"tree\": \"%s\", \"count\": %zu, \"hits\": %zu, "
                    "\"nodes_per_ray\": %.4f, \"triangles_per_ray\": %.4f, \"max_nodes\": %zu, "
                    "\"node_bytes_per_ray\": %.2f, \"tri_bytes_per_ray\": %.2f, \"bytes_per_ray\": %.2f, "
                    "\"seconds\": %.6f}",
                    i ? "," : "", r.rays.c_str(), r.mode.c_str(), r.tree.c_str(), r.count, r.hits, r.nodes, r.tris,
                    r.max_nodes, r.node_bytes, r.tri_bytes, r.node_bytes + r.tri_bytes, r.seconds);
    }
    std::printf("]}\n");
    return 0;
}
