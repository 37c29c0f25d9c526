// SASS size probes of the per-lane steps (bench/gpu/step_sizes.sh): each kernel runs
// one step once, straight-line, so the size of its .text section / 16 bytes (one
// sm_90 instruction) estimates the instructions one warp issues for that step.
// The warp model (kernels/include/cwbvh/kernels/warp_model.h) weights its phases with them.
#include "cwbvh/kernels/cwbvh_lane.h"
#include "cwbvh/kernels/gpu_common.h"
#include "cwbvh/kernels/traverse_bvh2.h"

namespace cwbvh {
namespace probe {

/// Empty frame: parameter loads and the final store, subtracted from the others.
__global__ void probe_empty(const uint32_t* in, uint32_t* out) { out[threadIdx.x] = in[threadIdx.x]; }

/// One CWBVH node step: load + visit_node (8 box tests, hit mask). kFast: the
/// common path, intersect_node_fast (rays that pass fast_node_test_applies);
/// otherwise intersect_node_scalar (its rare reach filter for unbounded axes included:
/// the probe's lane may hold norcp where that filter reads the reach; sizes only).
template <TriangleTest kTest, bool kFast>
__global__ void probe_cwbvh_node(const CwbvhNode* nodes, const Ray* rays, uint32_t* out, NodeScale scale) {
    CwbvhLane<kTest> l(gpu::load_ray(rays + threadIdx.x), scale);
    l.nray.zero_axes = kFast ? NodeRay::kFastBit : 0u;
    l.nray.frame = out[threadIdx.x + 64];  // as a kernel holds it: the set-up's check is not part of the step
    visit_node(l, load_node_words(nodes + out[threadIdx.x]), scale.frame_word);
    out[threadIdx.x] = l.node_group.hits ^ l.tri_group.hits ^ l.node_group.base ^ l.tri_group.base;
}

/// The node step as the kernel compiles it: the ray's set-up decides at run time which
/// test runs (NodeRay::fast), so the loaded node feeds both. The fast path of this probe
/// is its size minus probe_cwbvh_node<kTest, false> (the reference path alone). Sized
/// separately because the two can differ: with a node struct of bytes shared by both
/// tests, nvcc rebuilt every word of the fast test from bytes here (about 80
/// instructions per step) while probe_cwbvh_node<kTest, true> stayed lean (NodeWords).
template <TriangleTest kTest>
__global__ void probe_cwbvh_node_dispatch(const CwbvhNode* nodes, const Ray* rays, uint32_t* out, NodeScale scale) {
    CwbvhLane<kTest> l(gpu::load_ray(rays + threadIdx.x), scale);
    l.nray.zero_axes = out[threadIdx.x] & NodeRay::kFastBit;
    l.nray.frame = out[threadIdx.x + 64];
    visit_node(l, load_node_words(nodes + (out[threadIdx.x] & 0x7FFFFFFFu)), scale.frame_word);
    out[threadIdx.x] = l.node_group.hits ^ l.tri_group.hits ^ l.node_group.base ^ l.tri_group.base;
}

/// One triangle step: load + test.
template <TriangleTest kTest>
__global__ void probe_triangle(const TriangleRecord* tris, const Ray* rays, uint32_t* out) {
    CwbvhLane<kTest> l(gpu::load_ray(rays + threadIdx.x));
    const uint32_t ti = out[threadIdx.x];
    test_triangle(l, gpu::load_triangle(tris + ti), ti);
    out[threadIdx.x] = l.hit_tri ^ __float_as_uint(l.tmax);
}

/// The watertight test's first stage (load, shear, edge functions, sign test): all a
/// triangle test runs when the edge signs are mixed (a miss), i.e. on most tests.
__global__ void probe_triangle_edges(const TriangleRecord* tris, const Ray* rays, uint32_t* out) {
    CwbvhLane<TriangleTest::kWatertight> l(gpu::load_ray(rays + threadIdx.x));
    const TriangleRecord t = gpu::load_triangle(tris + out[threadIdx.x]);
    WatertightEdges e;
    const bool pass = watertight_edges(l.tri_test.w, t.v0, t.v1, t.v2, e);
    out[threadIdx.x] = pass ? __float_as_uint(e.eu + e.ev + e.ew) : 0u;
}

/// The watertight test's first two stages (edge signs, then the float range test):
/// all a triangle test runs for a triangle whose plane lies certainly beyond tmax (or
/// before tmin), the common case among those whose edge signs agree.
__global__ void probe_triangle_range(const TriangleRecord* tris, const Ray* rays, uint32_t* out) {
    CwbvhLane<TriangleTest::kWatertight> l(gpu::load_ray(rays + threadIdx.x));
    const TriangleRecord t = gpu::load_triangle(tris + out[threadIdx.x]);
    WatertightEdges e;
    const bool pass = watertight_edges(l.tri_test.w, t.v0, t.v1, t.v2, e) &&
                      !watertight_range_miss(l.tri_test.w, t.v0, t.v1, t.v2, l.tmin, l.tmax);
    out[threadIdx.x] = pass ? __float_as_uint(e.eu + e.ev + e.ew) : 0u;
}

/// A deferred hit (cwbvh_lane.h, test_triangle_deferred): the edge signs and the float
/// range stage with its bounds (watertight_range_interval), all that a triangle float
/// proves the closest so far costs; its double-precision distance waits for the refill.
__global__ void probe_triangle_interval(const TriangleRecord* tris, const Ray* rays, uint32_t* out) {
    CwbvhLane<TriangleTest::kWatertight> l(gpu::load_ray(rays + threadIdx.x));
    const TriangleRecord t = gpu::load_triangle(tris + out[threadIdx.x]);
    WatertightEdges e;
    float lo = 0.0f, hi = 0.0f;
    const bool pass = watertight_edges(l.tri_test.w, t.v0, t.v1, t.v2, e) &&
                      watertight_range_interval(l.tri_test.w, t.v0, t.v1, t.v2, l.tmin, l.tmax, l.tmax, lo, hi) ==
                          RangeVerdict::kInside &&
                      is_finite_nonzero_f(e.eu) && is_finite_nonzero_f(e.ev) && is_finite_nonzero_f(e.ew);
    out[threadIdx.x] = pass ? __float_as_uint(lo) ^ __float_as_uint(hi) : 0u;
}

/// The watertight test's per-ray set-up alone (ray load, shear constants): subtracted
/// from the triangle probes, which hold it too.
__global__ void probe_triangle_setup(const Ray* rays, uint32_t* out) {
    const WatertightRay w = make_watertight_ray(gpu::load_ray(rays + threadIdx.x));
    float sum = 0.0f;
    for (int a = 0; a < 3; ++a) sum += w.org[a] + w.dir[a] + w.mx[a] + w.my[a];
    out[threadIdx.x] = __float_as_uint(sum);
}

/// Per-ray set-up (ray load, NodeRay, triangle-test constants).
template <TriangleTest kTest>
__global__ void probe_ray_setup(const Ray* rays, uint32_t* out, NodeScale scale) {
    CwbvhLane<kTest> l(gpu::load_ray(rays + threadIdx.x), scale);
    l.nray.frame = out[threadIdx.x + 64];  // as in the node probes (whose set-up this is)
    // frame_word: the kernel loads it once per launch, not per node step.
    out[threadIdx.x] = __float_as_uint(l.nray.rcp[0] + l.nray.rcp[1] + l.nray.rcp[2] + l.nray.norcp[0] +
                                       l.nray.norcp[1] + l.nray.norcp[2]) ^ l.nray.octinv ^ l.nray.frame ^ scale.frame_word;
}

/// One BVH2 node step: 64-byte load, two robust slab tests.
__global__ void probe_bvh2_node(const Bvh2Node* nodes, const Ray* rays, uint32_t* out) {
    const Bvh2Ray r = make_bvh2_ray(gpu::load_ray(rays + threadIdx.x));
    const float4* np = reinterpret_cast<const float4*>(nodes + out[threadIdx.x]);
    const float4 a = __ldg(np), b = __ldg(np + 1), c = __ldg(np + 2);
    const int4 d = __ldg(reinterpret_cast<const int4*>(np) + 3);
    const float lo0[3] = {a.x, a.z, c.x}, hi0[3] = {a.y, a.w, c.y};
    const float lo1[3] = {b.x, b.z, c.z}, hi1[3] = {b.y, b.w, c.w};
    float t0 = 0, t1 = 0;
    const bool h0 = intersect_box_robust(r, lo0, hi0, 0.0f, 1e30f, t0);
    const bool h1 = intersect_box_robust(r, lo1, hi1, 0.0f, 1e30f, t1);
    out[threadIdx.x] = (h0 ? d.x : 0) ^ (h1 ? d.y : 0) ^ (t1 < t0);
}

template __global__ void probe_cwbvh_node<TriangleTest::kWatertight, true>(const CwbvhNode*, const Ray*, uint32_t*,
                                                                        NodeScale);
template __global__ void probe_cwbvh_node<TriangleTest::kWatertight, false>(const CwbvhNode*, const Ray*, uint32_t*,
                                                                         NodeScale);
template __global__ void probe_cwbvh_node_dispatch<TriangleTest::kWatertight>(const CwbvhNode*, const Ray*, uint32_t*,
                                                                             NodeScale);
template __global__ void probe_triangle<TriangleTest::kWatertight>(const TriangleRecord*, const Ray*, uint32_t*);
template __global__ void probe_triangle<TriangleTest::kFast>(const TriangleRecord*, const Ray*, uint32_t*);
template __global__ void probe_ray_setup<TriangleTest::kWatertight>(const Ray*, uint32_t*, NodeScale);

}  // namespace probe
}  // namespace cwbvh
