// libFuzzer target for spec 7a's first sentence: "the rules of section 7 make a file safe to
// traverse". Any bytes are resealed (fuzz_file.h) and validated; a file that passes is traced
// by every traversal a reader can run on it, with rays aimed at its own triangles from
// outside and inside its bounds, axis-parallel rays (zero direction components), rays with
// subnormal and huge components, tmin < 0 and -0, and tmax = +inf:
//   - traverse_cwbvh with the reference node test, and with the fast node test under the
//     file's node_scale (as DeviceScene::upload computes it for the GPU);
//   - the warp model (warp_model.h): the GPU kernels' own lane code under their warp rules
//     (postponing, the shared stack and its spill, dynamic fetch), CWBVH and BVH2;
//   - the BVH2 traversal over BVH2 and BV2L, and the two-level traversal (format 1.2);
//   - the inline query a renderer calls (query.h, over a SceneView with the fast test's
//     constants), whose TRIS record and INST index the caller reads: both must be in range.
// What must hold on every validated file:
//   - no crash, no hang (libFuzzer's -timeout), nothing ASan or UBSan reports;
//   - no kBadIndex and no kStackOverflow (depth <= 32, rule 5113: the CPU stack holds 64);
//   - kInvalidRay exactly for the rays ray_is_traceable refuses;
//   - a hit lies in [tmin, tmax] and names a stored triangle (prim < PMAP total).
// And where the deep checks (D1-D7) pass and no triangle is split over several TRIS records
// (for those D2 is exact; D3, for split ones, samples 45 points per triangle and reads the
// first record's vertices), i.e. the boxes hold their geometry: every
// traversal finds the same closest t as the reference (both node tests are conservative, so
// they may differ only in which of equal-t triangles they report) and the same any-hit
// verdict. A failure is a bug in the validator (a rule missing) or in a traversal.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "cwbvh/format/validate.h"
#include "cwbvh/kernels/cpu_trace.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/query.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/warp_model.h"
#include "fuzz_file.h"

namespace {

using namespace cwbvh;
using fuzz::FileSections;

[[noreturn]] void fail(const char* what, size_t ray) {
    std::fprintf(stderr, "fuzz_trace: %s (ray %zu)\n", what, ray);
    std::abort();
}

/// Rays for a scene whose triangles span [lo, hi]: at triangle centroids from outside and
/// inside the bounds, axis-parallel through them, and the delicate direction components.
std::vector<Ray> make_rays(const std::vector<TriangleRecord>& tris) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (const TriangleRecord& t : tris)
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::fmin(lo[a], std::fmin(t.v0[a], std::fmin(t.v1[a], t.v2[a])));
            hi[a] = std::fmax(hi[a], std::fmax(t.v0[a], std::fmax(t.v1[a], t.v2[a])));
        }
    if (tris.empty())
        for (int a = 0; a < 3; ++a) lo[a] = -1.0f, hi[a] = 1.0f;
    float center[3], ext[3];
    for (int a = 0; a < 3; ++a) {
        // In double: a box near FLT_MAX has no float centre or extent.
        center[a] = float(0.5 * (double(lo[a]) + double(hi[a])));
        ext[a] = float(std::fmin(double(hi[a]) - double(lo[a]) + 1.0, 1e30));
    }
    std::vector<Ray> rays;
    auto add = [&](const float o[3], const float d[3], float tmin, float tmax) {
        Ray r;
        for (int a = 0; a < 3; ++a) r.org[a] = o[a], r.dir[a] = d[a];
        r.tmin = tmin;
        r.tmax = tmax;
        rays.push_back(r);
    };
    const size_t n = tris.size(), targets = n < 6 ? n : 6;
    for (size_t k = 0; k < targets; ++k) {
        const TriangleRecord& t = tris[k * n / targets];
        float c[3];
        for (int a = 0; a < 3; ++a) c[a] = float((double(t.v0[a]) + double(t.v1[a]) + double(t.v2[a])) / 3.0);
        // From outside the bounds along each axis, from the centre, and along the axes.
        for (int a = 0; a < 3; ++a)
            for (int s = -1; s <= 1; s += 2) {
                float o[3] = {c[0], c[1], c[2]}, d[3];
                o[a] = s < 0 ? lo[a] - ext[a] : hi[a] + ext[a];
                for (int b = 0; b < 3; ++b) d[b] = c[b] - o[b] + (b == a ? 0.0f : 1e-3f * ext[b] * float(s));
                add(o, d, 0.0f, INFINITY);
                const float axis[3] = {a == 0 ? float(-s) : 0.0f, a == 1 ? float(-s) : 0.0f, a == 2 ? float(-s) : 0.0f};
                add(o, axis, 0.0f, INFINITY);  // zero components: the exact "origin inside the slab" test
                float tiny[3] = {axis[0], axis[1], axis[2]};
                tiny[(a + 1) % 3] = 1e-40f * float(s);  // subnormal: the reach culls that axis
                add(o, tiny, -0.0f, INFINITY);
            }
        float d[3];
        for (int b = 0; b < 3; ++b) d[b] = c[b] - center[b] + 1e-3f * ext[b];
        add(center, d, 0.0f, 2.0f);
        add(center, d, -1.0f, 1.0f);  // tmin < 0: open axes
        const float huge[3] = {d[0] * 3e37f, d[1] == 0.0f ? 1e38f : d[1] * 3e37f, -2e38f};
        add(center, huge, 0.0f, INFINITY);  // |d| > 2^126: RN(1/d) subnormal
    }
    const float o[3] = {center[0], center[1], center[2]}, z[3] = {0, 0, 0}, d[3] = {1, 2, 3};
    add(o, z, 0.0f, 1.0f);         // not traceable: zero direction
    add(o, d, 1.0f, 0.0f);         // not traceable: tmin > tmax
    add(o, d, NAN, 1.0f);          // not traceable
    return rays;
}

bool same_closest(const Hit& a, const Hit& b) {
    if ((a.prim == kMissPrim) != (b.prim == kMissPrim)) return false;
    return a.prim == kMissPrim || std::memcmp(&a.t, &b.t, sizeof a.t) == 0;
}

/// The per-ray checks every traversal's answer must pass on a validated file.
void check(const char* who, const std::vector<Ray>& rays, const std::vector<Hit>& hits,
           const std::vector<TraceStatus>& statuses, uint64_t stored) {
    for (size_t i = 0; i < rays.size(); ++i) {
        const Ray& r = rays[i];
        const bool traceable = ray_is_traceable(r);
        const TraceStatus st = statuses[i];
        if (st == TraceStatus::kBadIndex || st == TraceStatus::kStackOverflow) {
            std::fprintf(stderr, "%s: status %u on a validated file\n", who, unsigned(st));
            fail("bad index or stack overflow", i);
        }
        if ((st == TraceStatus::kInvalidRay) == traceable) fail(who, i);
        const Hit& h = hits[i];
        if (h.prim == kMissPrim) continue;
        if (!(h.t >= r.tmin && h.t <= r.tmax) || h.prim >= stored) {
            std::fprintf(stderr, "%s: hit t %g prim %u outside [%g, %g] or >= %llu\n", who, double(h.t), h.prim,
                         double(r.tmin), double(r.tmax), (unsigned long long)stored);
            fail("hit out of range", i);
        }
    }
}

/// traverse_cwbvh over NODE with the given scene constants (NodeScale{}: the reference).
template <TriangleTest kTest, HitMode kMode>
void trace_nodes(const FileSections& f, const NodeScale& scale, const std::vector<Ray>& rays, std::vector<Hit>& hits,
                 std::vector<TraceStatus>& statuses) {
    for (size_t i = 0; i < rays.size(); ++i) {
        LocalStack<kCpuStackSize> stack;
        statuses[i] = traverse_cwbvh<kTest, kMode>(f.nodes.data(), uint32_t(f.nodes.size()), f.tris.data(),
                                                   uint32_t(f.tris.size()), rays[i], hits[i], stack, nullptr,
                                                   NoPostpone(), scale);
    }
}

/// The warp model's statuses are counts; a clean run has none of the bad kinds.
void check_model(const char* who, const WarpModelStats& s, const std::vector<Ray>& rays) {
    size_t untraceable = 0;
    for (const Ray& r : rays) untraceable += ray_is_traceable(r) ? 0 : 1;
    if (s.bad_indices != 0 || s.stack_overflows != 0 || s.invalid_rays != untraceable) {
        std::fprintf(stderr, "%s: %llu bad indices, %llu overflows, %llu invalid rays (%zu expected)\n", who,
                     (unsigned long long)s.bad_indices, (unsigned long long)s.stack_overflows,
                     (unsigned long long)s.invalid_rays, untraceable);
        fail("warp model status", 0);
    }
    // A deferred hit (cwbvh_lane.h) the whole test does not confirm bit for bit: the float
    // bounds are wrong for some triangle, whatever the file holds.
    if (s.finalize_failures != 0) {
        std::fprintf(stderr, "%s: %llu deferred hits not confirmed by the whole test\n", who,
                     (unsigned long long)s.finalize_failures);
        fail("deferred hit", 0);
    }
}

void compare(const char* who, const std::vector<Hit>& ref, const std::vector<Hit>& other, bool any_hit) {
    for (size_t i = 0; i < ref.size(); ++i) {
        const bool same = any_hit ? (ref[i].prim == kMissPrim) == (other[i].prim == kMissPrim)
                                  : same_closest(ref[i], other[i]);
        if (!same) {
            std::fprintf(stderr, "%s: t %a prim %u, reference t %a prim %u\n", who, double(other[i].t), other[i].prim,
                         double(ref[i].t), ref[i].prim);
            fail("answer differs from the reference on a deep-checked file", i);
        }
    }
}

/// The inline query (query.h) over `view`: the same answers as `ref` (the traversal it wraps,
/// with the same constants), a TRIS record that holds the hit's prim, an INST index in range.
void check_query(const FileSections& f, const SceneView& view, const std::vector<Ray>& rays,
                 const std::vector<Hit>& ref, bool deep_ok) {
    for (size_t i = 0; i < rays.size(); ++i) {
        const QueryHit q = intersect(view, rays[i]);
        if (q.status == TraceStatus::kBadIndex || q.status == TraceStatus::kStackOverflow) fail("query status", i);
        if (q.hit.prim == kMissPrim) {
            if (q.record != kInvalidIndex || q.instance != kInvalidIndex) fail("query: a miss with a record", i);
        } else {
            if (q.record >= f.tris.size() || f.tris[q.record].prim != q.hit.prim) fail("query: record", i);
            if (view.two_level() ? q.instance >= f.instances.size() : q.instance != kInvalidIndex)
                fail("query: instance", i);
        }
        if (deep_ok && !same_closest(ref[i], q.hit)) fail("query: answer differs from the reference", i);
        if (occluded(view, rays[i]) != (q.hit.prim != kMissPrim) && deep_ok) fail("query: occluded", i);
    }
}

void trace_single_level(const FileSections& f, const std::vector<Ray>& rays, bool deep_ok) {
    const size_t n = rays.size();
    std::vector<Hit> ref(n), hits(n);
    std::vector<TraceStatus> st(n);
    trace_nodes<TriangleTest::kWatertight, HitMode::kClosest>(f, NodeScale{}, rays, ref, st);
    check("reference", rays, ref, st, f.stored);
    const NodeScale scale = node_scale(f.nodes.data(), f.nodes.size());
    trace_nodes<TriangleTest::kWatertight, HitMode::kClosest>(f, scale, rays, hits, st);
    check("fast node test", rays, hits, st, f.stored);
    if (deep_ok) compare("fast node test", ref, hits, false);
    SceneView view{};
    view.sections.nodes = f.nodes.data();
    view.sections.node_count = uint32_t(f.nodes.size());
    view.sections.tris = f.tris.data();
    view.sections.tri_count = uint32_t(f.tris.size());
    view.sections.node_scale = scale;
    check_query(f, view, rays, ref, deep_ok);
    trace_nodes<TriangleTest::kWatertight, HitMode::kAny>(f, scale, rays, hits, st);
    check("fast node test, any hit", rays, hits, st, f.stored);
    if (deep_ok) compare("fast node test, any hit", ref, hits, true);

    WarpModelOptions o;
    o.warps = 2;  // two warps share the ray counter: refills and fetches happen
    const WarpModelStats s = model_cwbvh_warps(f.nodes.data(), f.nodes.size(), f.tris.data(), f.tris.size(),
                                               rays.data(), hits.data(), n, o);
    check_model("warp model", s, rays);
    std::vector<TraceStatus> ok(n, TraceStatus::kOk);
    for (size_t i = 0; i < n; ++i)
        if (!ray_is_traceable(rays[i])) ok[i] = TraceStatus::kInvalidRay;
    check("warp model", rays, hits, ok, f.stored);
    if (deep_ok) compare("warp model", ref, hits, false);

    for (const std::vector<Bvh2Node>* tree : {&f.bvh2, &f.bv2l}) {
        if (tree->empty()) continue;
        CpuTraceOptions co;
        co.threads = 1;
        co.statuses = st.data();
        (void)trace_bvh2_cpu(tree->data(), tree->size(), f.tris.data(), f.tris.size(), rays.data(), hits.data(), n, co);
        check("bvh2", rays, hits, st, f.stored);
        if (deep_ok) compare("bvh2", ref, hits, false);
        const WarpModelStats b = model_bvh2_warps(tree->data(), tree->size(), f.tris.data(), f.tris.size(),
                                                  rays.data(), hits.data(), n, o);
        check_model("bvh2 warp model", b, rays);
        check("bvh2 warp model", rays, hits, ok, f.stored);
        if (deep_ok) compare("bvh2 warp model", ref, hits, false);
    }
}

void trace_two_level(const FileSections& f, const std::vector<Ray>& rays, bool deep_ok) {
    TwoLevelScene scene{f.top.data(),    uint32_t(f.top.size()),   f.instances.data(), uint32_t(f.instances.size()),
                        f.meshes.data(), uint32_t(f.meshes.size()), f.nodes.data(),     uint32_t(f.nodes.size()),
                        f.tris.data(),   uint32_t(f.tris.size())};
    const size_t n = rays.size();
    std::vector<Hit> ref(n), hits(n);
    std::vector<uint32_t> inst(n);
    std::vector<TraceStatus> st(n);
    CpuTraceOptions co;
    co.threads = 1;
    co.statuses = st.data();
    (void)trace_two_level_cpu(scene, rays.data(), ref.data(), inst.data(), n, co);
    check("two-level", rays, ref, st, f.stored);
    for (size_t i = 0; i < n; ++i)
        if ((ref[i].prim == kMissPrim) != (inst[i] == kInvalidIndex) ||
            (inst[i] != kInvalidIndex && inst[i] >= f.instances.size()))
            fail("two-level instance index", i);
    // As DeviceScene::upload: the fast test's constants over NODE and TLAS.
    scene.node_scale = merge_node_scale(node_scale(f.nodes.data(), f.nodes.size()), node_scale(f.top.data(), f.top.size()));
    (void)trace_two_level_cpu(scene, rays.data(), hits.data(), inst.data(), n, co);
    check("two-level, fast node test", rays, hits, st, f.stored);
    if (deep_ok) compare("two-level, fast node test", ref, hits, false);
    check_query(f, SceneView{scene}, rays, ref, deep_ok);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    std::vector<uint8_t> copy(data, data + size);
    fuzz::reseal(copy);
    FileLayout layout;
    if (!validate(copy, ValidateOptions{}, &layout).ok()) return 0;
    const FileSections f(layout);
    const bool deep_ok = f.deep_checks_pass() && !f.has_split_triangles();
    const std::vector<Ray> rays = make_rays(f.tris);
    if (f.two_level())
        trace_two_level(f, rays, deep_ok);
    else
        trace_single_level(f, rays, deep_ok);
    return 0;
}
