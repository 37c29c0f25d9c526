// Error against the exact oracle, per traversal configuration, with run time:
// each configuration becomes one point (Mrays/s, mismatch rate).
//
//   cwbvh_bench_error --reference REF.cwbvh [--config NAME,FILE,TREE,TEST]...
//                     [--width W] [--height H] [--bounces B] [--repeats R]
//                     [--rel-tol X] [--brute-check N] [--camera ex,ey,ez,tx,ty,tz,fov]
//   TREE: cwbvh | bvh2 (the file's BVH2 section)   TEST: watertight | fast
//
// Rays: primary rays (W x H) of --camera (bench/run.py passes the scene's first view of
// views/catalog.txt) or default_camera, and the diffuse rays of bounce B
// (ray_gen.h), generated once from REF; every configuration traces the same rays.
//
// Oracle: oracle/include/cwbvh/oracle/oracle.h's exact predicate (expansion arithmetic) and
// its closest-hit rule (ties and range ends within the float-precision
// tolerance `tol` of oracle_trace). Brute force is O(rays x triangles), so the
// candidates come from our own median-split BVH over the distinct triangles of
// REF (whole triangles, no spatial splits, independent of the compiler), tested
// against the *line* in double with every box padded by 2^-20 of its coordinate
// magnitude: a triangle the line meets in [tmin - 2 tol, tmax + 2 tol] is always
// a candidate (the double slab error is ~1e-16 relative, far below the pad).
// --brute-check N re-runs N rays through the plain brute-force oracle_trace and
// reports disagreements (expected 0).
//
// Classes per ray (closest hit): skipped (a mismatch on a ray whose oracle has a
// hit within tol of tmin/tmax: ambiguous at float precision), false_miss, false_hit, wrong_prim (prim not among the
// oracle's ties), t_error (right prim, |t - t_oracle| > rel_tol * t_oracle),
// else ok. Prints one JSON object.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numeric>
#include <string>
#include <unordered_map>
#include <vector>

#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/ray_gen.h"
#include "cwbvh/loader/loader.h"
#include "cwbvh/oracle/oracle.h"

namespace {
[[noreturn]] void die(const std::string& m) {
    std::fprintf(stderr, "cwbvh_bench_error: %s\n", m.c_str());
    std::exit(2);
}

struct OBox {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    void grow(const float* p) {
        for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], p[a]), hi[a] = std::max(hi[a], p[a]);
    }
    void grow(const OBox& b) { grow(b.lo), grow(b.hi); }
};
struct ONode {
    OBox box;
    uint32_t left = 0, right = 0;  // internal
    uint32_t first = 0, count = 0; // leaf when count > 0
};

class OracleBvh {
public:
    explicit OracleBvh(std::vector<cwbvh::TriangleRecord> t) : tris_(std::move(t)) {
        order_.resize(tris_.size());
        std::iota(order_.begin(), order_.end(), 0u);
        boxes_.resize(tris_.size());
        cent_.resize(tris_.size());
        for (size_t i = 0; i < tris_.size(); ++i) {
            boxes_[i].grow(tris_[i].v0), boxes_[i].grow(tris_[i].v1), boxes_[i].grow(tris_[i].v2);
            for (int a = 0; a < 3; ++a) cent_[i][a] = 0.5 * (double(boxes_[i].lo[a]) + boxes_[i].hi[a]);
        }
        nodes_.reserve(2 * tris_.size() / 2 + 8);
        build(0, uint32_t(tris_.size()));
        for (const auto& tr : tris_)
            for (int a = 0; a < 3; ++a)
                ext_ = std::max({ext_, std::fabs((long double)tr.v0[a]), std::fabs((long double)tr.v1[a]),
                                 std::fabs((long double)tr.v2[a])});
    }
    const std::vector<cwbvh::TriangleRecord>& triangles() const { return tris_; }

    cwbvh::test::OracleResult trace(const cwbvh::Ray& r) const {
        cwbvh::test::OracleResult res;
        if (!cwbvh::ray_is_traceable(r)) return res;
        long double m = 0, dl = 0;
        for (int a = 0; a < 3; ++a) {
            m = std::max(m, std::fabs((long double)r.org[a]));
            dl = std::max(dl, std::fabs((long double)r.dir[a]));
        }
        const long double tol = (m + ext_) / dl * 3.814697265625e-06L;  // as oracle_trace
        res.tol = tol;
        const double lo_t = double(r.tmin - 2 * tol), hi_t = double(r.tmax + 2 * tol);
        std::vector<std::pair<long double, uint32_t>> hits;
        uint32_t stack[128];
        int sp = 0;
        stack[sp++] = 0;
        while (sp) {
            const ONode& n = nodes_[stack[--sp]];
            if (!line_hits(r, n.box, lo_t, hi_t)) continue;
            if (n.count) {
                for (uint32_t k = n.first; k < n.first + n.count; ++k) {
                    const cwbvh::TriangleRecord& tr = tris_[order_[k]];
                    const auto o = cwbvh::test::oracle_triangle(r, tr.v0, tr.v1, tr.v2);
                    if (!o.hit) continue;
                    if (std::fabs(o.t - r.tmin) <= tol || std::fabs(o.t - r.tmax) <= tol) res.near_range_end = true;
                    if (o.t < r.tmin || o.t > r.tmax) continue;
                    hits.push_back({o.t, tr.prim});
                    if (o.t < res.t || (o.t == res.t && tr.prim < res.prim)) {
                        res.t = o.t, res.prim = tr.prim, res.hit = true;
                    }
                }
            } else {
                if (sp + 2 > 128) die("oracle BVH too deep");
                stack[sp++] = n.left;
                stack[sp++] = n.right;
            }
        }
        for (const auto& h : hits)
            if (h.first <= res.t + tol) res.ties.push_back(h.second);
        return res;
    }

private:
    static bool line_hits(const cwbvh::Ray& r, const OBox& b, double lo_t, double hi_t) {
        double tn = lo_t, tf = hi_t;
        for (int a = 0; a < 3; ++a) {
            const double pad = 9.5367431640625e-07 * (std::fabs(double(b.lo[a])) + std::fabs(double(b.hi[a]))) + 1e-300;
            const double lo = double(b.lo[a]) - pad, hi = double(b.hi[a]) + pad, o = r.org[a], d = r.dir[a];
            if (d == 0.0) {
                if (o < lo || o > hi) return false;
                continue;
            }
            double t0 = (lo - o) / d, t1 = (hi - o) / d;
            if (t0 > t1) std::swap(t0, t1);
            tn = std::max(tn, t0);
            tf = std::min(tf, t1);
        }
        return tn <= tf;
    }
    uint32_t build(uint32_t first, uint32_t count) {
        const uint32_t id = uint32_t(nodes_.size());
        nodes_.emplace_back();
        OBox box, cb;
        for (uint32_t k = first; k < first + count; ++k) {
            box.grow(boxes_[order_[k]]);
            const float c[3] = {float(cent_[order_[k]][0]), float(cent_[order_[k]][1]), float(cent_[order_[k]][2])};
            cb.grow(c);
        }
        nodes_[id].box = box;
        if (count <= 4) {
            nodes_[id].first = first, nodes_[id].count = count;
            return id;
        }
        int axis = 0;
        for (int a = 1; a < 3; ++a)
            if (cb.hi[a] - cb.lo[a] > cb.hi[axis] - cb.lo[axis]) axis = a;
        const uint32_t mid = first + count / 2;
        std::nth_element(order_.begin() + first, order_.begin() + mid, order_.begin() + first + count,
                         [&](uint32_t x, uint32_t y) { return cent_[x][axis] < cent_[y][axis]; });
        const uint32_t l = build(first, mid - first);
        const uint32_t rr = build(mid, first + count - mid);
        nodes_[id].left = l, nodes_[id].right = rr;
        return id;
    }
    std::vector<cwbvh::TriangleRecord> tris_;
    std::vector<uint32_t> order_;
    std::vector<OBox> boxes_;
    std::vector<std::array<double, 3>> cent_;
    std::vector<ONode> nodes_;
    long double ext_ = 0;
};

struct Config {
    std::string name, file, tree, test;
};
double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}
}  // namespace

int main(int argc, char** argv) {
    std::string ref;
    std::vector<Config> configs;
    uint32_t width = 100, height = 100, bounces = 1, brute = 100;
    int repeats = 5;
    double rel_tol = 1e-5;
    std::string camera_text;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) die("missing value after " + a);
            return argv[++i];
        };
        if (a == "--reference") ref = next();
        else if (a == "--config") {
            const std::string v = next();
            Config c;
            size_t p0 = v.find(','), p1 = v.find(',', p0 + 1), p2 = v.find(',', p1 + 1);
            if (p0 == std::string::npos || p1 == std::string::npos || p2 == std::string::npos)
                die("--config NAME,FILE,TREE,TEST");
            c.name = v.substr(0, p0), c.file = v.substr(p0 + 1, p1 - p0 - 1), c.tree = v.substr(p1 + 1, p2 - p1 - 1),
            c.test = v.substr(p2 + 1);
            if ((c.tree != "cwbvh" && c.tree != "bvh2") || (c.test != "watertight" && c.test != "fast"))
                die("--config: TREE cwbvh|bvh2, TEST watertight|fast");
            configs.push_back(c);
        } else if (a == "--width") width = std::atoi(next().c_str());
        else if (a == "--height") height = std::atoi(next().c_str());
        else if (a == "--bounces") bounces = std::atoi(next().c_str());
        else if (a == "--repeats") repeats = std::atoi(next().c_str());
        else if (a == "--rel-tol") rel_tol = std::atof(next().c_str());
        else if (a == "--brute-check") brute = std::atoi(next().c_str());
        else if (a == "--camera") camera_text = next();
        else die("unknown argument " + a);
    }
    if (ref.empty() || repeats < 1 || bounces < 1) die("usage: --reference REF.cwbvh --config NAME,FILE,TREE,TEST ...");

    auto rf = cwbvh::File::open(ref);
    if (!rf.ok()) die(rf.error().message);
    const auto rnodes = rf->nodes();
    const auto rtris = rf->triangles();
    std::vector<cwbvh::Ray> sets[2];
    cwbvh::Camera camera = cwbvh::default_camera(*rf->bounds());
    if (!camera_text.empty()) {
        if (const cwbvh::Result r = cwbvh::parse_camera(camera_text, camera); !r.ok()) die(r.message);
    }
    sets[0] = cwbvh::camera_rays(camera, width, height);
    sets[1] = cwbvh::diffuse_rays(rnodes.data(), rnodes.size(), rtris.data(), rtris.size(), sets[0], bounces, 7u, 0)
                  .rays;

    // Distinct triangles (spatial splits store a triangle more than once).
    std::vector<cwbvh::TriangleRecord> uniq;
    {
        std::vector<char> seen;
        for (const auto& t : rtris) {
            if (t.prim >= seen.size()) seen.resize(size_t(t.prim) + 1, 0);
            if (!seen[t.prim]) seen[t.prim] = 1, uniq.push_back(t);
        }
    }
    const OracleBvh oracle(uniq);
    std::vector<cwbvh::test::OracleResult> truth[2];
    size_t brute_checked = 0, brute_disagree = 0;
    for (int s = 0; s < 2; ++s) {
        truth[s].resize(sets[s].size());
        for (size_t i = 0; i < sets[s].size(); ++i) truth[s][i] = oracle.trace(sets[s][i]);
        const size_t step = brute ? std::max<size_t>(1, sets[s].size() / brute) : 0;
        for (size_t i = 0; step && i < sets[s].size() && brute_checked < size_t(2 * brute); i += step) {
            const auto b = cwbvh::test::oracle_trace(sets[s][i], uniq.data(), uniq.size(), truth[s][i].tol);
            const auto& a = truth[s][i];
            ++brute_checked;
            if (a.hit != b.hit || a.near_range_end != b.near_range_end || (a.hit && a.t != b.t)) ++brute_disagree;
        }
    }

    std::printf("{\"reference\": \"%s\", \"triangles\": %zu, \"rays\": {\"primary\": %zu, \"diffuse\": %zu}, "
                "\"rel_tol\": %g, \"repeats\": %d, \"brute_check\": {\"rays\": %zu, \"disagreements\": %zu},\n"
                " \"rows\": [",
                ref.c_str(), uniq.size(), sets[0].size(), sets[1].size(), rel_tol, repeats, brute_checked,
                brute_disagree);
    bool first_row = true;
    for (const Config& c : configs) {
        auto f = cwbvh::File::open(c.file);
        if (!f.ok()) die(f.error().message);
        if (c.tree == "bvh2" && f->bvh2().empty()) die(c.file + ": no BVH2 section");
        for (int s = 0; s < 2; ++s) {
            const auto& rays = sets[s];
            std::vector<cwbvh::Hit> hits(rays.size());
            std::vector<double> secs;
            // Each repeat traces the set `loops` times (>= ~50 ms per repeat) and
            // reports the time per pass; the median of the repeats is kept.
            int loops = 1;
            for (int r = 0; r < repeats + 1; ++r) {
                double total = 0;
                for (int l = 0; l < loops; ++l) {
                cwbvh::CpuTraceOptions o;
                o.threads = 1;
                o.test = c.test == "fast" ? cwbvh::TriangleTest::kFast : cwbvh::TriangleTest::kWatertight;
                const auto st = c.tree == "cwbvh"
                                    ? cwbvh::trace_cwbvh_cpu(f->nodes().data(), f->nodes().size(),
                                                             f->triangles().data(), f->triangles().size(), rays.data(),
                                                             hits.data(), rays.size(), o)
                                    : cwbvh::trace_bvh2_cpu(f->bvh2().data(), f->bvh2().size(), f->triangles().data(),
                                                            f->triangles().size(), rays.data(), hits.data(),
                                                            rays.size(), o);
                total += st.seconds;
                }
                if (r == 0) {  // warm-up pass: choose the loop count
                    loops = std::max(1, std::min(1000, int(0.05 / std::max(total, 1e-6)) + 1));
                    continue;
                }
                secs.push_back(total / loops);
            }
            size_t skipped = 0, fmiss = 0, fhit = 0, wprim = 0, terr = 0, ok = 0;
            double max_rel = 0;
            for (size_t i = 0; i < rays.size(); ++i) {
                const auto& t = truth[s][i];
                const bool h = hits[i].prim != cwbvh::kMissPrim;
                // A mismatch on a ray with an oracle hit within tol of tmin/tmax
                // (typically a diffuse ray's own triangle just behind its origin)
                // is ambiguous at float precision: counted as skipped, not as error.
                size_t* bad = nullptr;
                if (!t.hit && h) bad = &fhit;
                else if (t.hit && !h) bad = &fmiss;
                else if (t.hit && std::find(t.ties.begin(), t.ties.end(), hits[i].prim) == t.ties.end()) bad = &wprim;
                else if (t.hit) {
                    const double rel = double(std::fabs((long double)hits[i].t - t.t) / std::fabs(t.t));
                    max_rel = std::max(max_rel, rel);
                    if (rel > rel_tol) bad = &terr;
                }
                if (!bad) ++ok;
                else if (t.near_range_end) ++skipped;
                else ++*bad;
            }
            const double med = median(secs);
            std::printf("%s\n  {\"config\": \"%s\", \"file\": \"%s\", \"tree\": \"%s\", \"test\": \"%s\", "
                        "\"rays\": \"%s\", \"count\": %zu, \"seconds\": %.6f, \"mrays_per_s\": %.4f, "
                        "\"skipped\": %zu, \"false_miss\": %zu, \"false_hit\": %zu, \"wrong_prim\": %zu, "
                        "\"t_error\": %zu, \"ok\": %zu, \"max_rel_t_error\": %.3e}",
                        first_row ? "" : ",", c.name.c_str(), c.file.c_str(), c.tree.c_str(), c.test.c_str(),
                        s == 0 ? "primary" : "diffuse", rays.size(), med, med > 0 ? rays.size() / med / 1e6 : 0.0,
                        skipped, fmiss, fhit, wprim, terr, ok, max_rel);
            first_row = false;
        }
    }
    std::printf("]}\n");
    return 0;
}
