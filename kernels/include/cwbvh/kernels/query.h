// Inline ray queries: one ray traced by the calling thread, from a renderer's own
// kernel (a megakernel path tracer, a shading or simulation kernel that needs a
// visibility answer in the middle of its work) or from host code.
//
//     __global__ void shade(cwbvh::SceneView scene, ...) {
//         const cwbvh::QueryHit h = cwbvh::intersect(scene, ray);          // closest hit
//         const bool blocked = cwbvh::occluded(scene, shadow_ray);       // any hit
//     }
//     // host: DeviceScene ds = ...; shade<<<g, b, 0, s>>>(ds.view(), ...);
//
// What it runs: the shared traversal loops (traverse.h for a single-level scene,
// traverse_two_level.h for a two-level one), with the scene's fast node test
// constants where the view has them (DeviceScene::view(): on sm_80 and later, as the
// wavefront kernels), the watertight triangle test by default. With it a hit is the CPU
// reference's hit bit for bit (tests/kernels/query_test.cpp on the host, and on a GPU
// cwbvh_gpu_check against trace_cwbvh_cpu / trace_two_level_cpu): the watertight test's
// answer depends on the ray and the triangle alone (no order, no FMA contraction), its t
// is the double plane distance (within ~2^-52 times the cancellation of the exact one;
// spec/rays.md "Defined answers"), and both node tests are conservative by more than
// that error, so they find the same hits, visited in the same order.
// TriangleTest::kFast gives no such guarantee.
//
// What it does not do: the wavefront kernels' warp-level work (dynamic ray fetch,
// triangle postponing, the stack in shared memory). The stack is the calling thread's
// (LocalStack: 64 entries of 8 bytes, in local memory on a GPU; the overload that takes a
// Stack& accepts another type with the same push/pop/empty members, e.g. one in shared
// memory). For large batches of rays that are all ready at once, cwbvh::trace (trace.h) is
// the faster call; cwbvh_gpu_check prints both.
//
// Node and triangle arrays must be 16-byte aligned on the device (DeviceScene's are).
#pragma once

#include <cstdint>
#include <type_traits>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/traverse_two_level.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

/// One scene as a query reads it: pointers and counts of its sections, in the memory of
/// the code that queries (device pointers from DeviceScene::view(), host pointers from
/// host_view() in two_level_file.h). Trivially copyable: pass it to a kernel by value.
/// A single-level scene has top_node_count == 0 and reads only nodes and tris;
/// sections.node_scale holds the fast node test's constants (NodeScale{}: the reference
/// node test everywhere).
struct SceneView {
    TwoLevelScene sections;
    CWBVH_HD bool two_level() const { return sections.top_node_count != 0; }
};
static_assert(std::is_trivially_copyable_v<SceneView>, "SceneView is passed to kernels by value");

/// A single-level scene's view: NODE and TRIS (and the fast node test's constants).
CWBVH_HD inline SceneView single_level_view(const CwbvhNode* nodes, uint32_t node_count, const TriangleRecord* tris,
                                            uint32_t tri_count, const NodeScale& scale = NodeScale{}) {
    return SceneView{TwoLevelScene{nullptr, 0, nullptr, 0, nullptr, 0, nodes, node_count, tris, tri_count, scale}};
}

/// A query's answer. hit: t (in the ray's parameter), u, v and the stored triangle's prim
/// (the TRIS record's id, as the Hit records of trace() and the hit files), or a miss
/// (prim == kMissPrim, t = +inf). record: the TRIS index of the hit's record, whose
/// vertices (sections.tris[record]) are what a shader reads for the normal; in a two-level
/// scene they are in the instance's object space (world space: apply
/// sections.instances[instance].object_to_world, as examples/inline_ao.h does);
/// kInvalidIndex for a miss. instance: the INST index of a two-level hit, else
/// kInvalidIndex. status: kOk, or why the answer is not exact, with a miss or the closest
/// hit found so far: kInvalidRay (a ray that ray_is_traceable refuses, or an empty
/// scene: a miss), kStackOverflow (a tree deeper than the stack), kBadIndex (a corrupt
/// tree), kWrongScene (a query compiled for the other kind of scene: a miss).
struct QueryHit {
    Hit hit;
    uint32_t record;
    uint32_t instance;
    TraceStatus status;
};
static_assert(sizeof(QueryHit) == 28, "QueryHit: no padding (device arrays of it, byte comparisons)");

/// Which scenes a query's code handles. kEither: both loops are compiled into the
/// caller; kSingleLevel or kTwoLevel: one loop, for a kernel that knows its scene. A view
/// of the other kind is then answered with a miss and TraceStatus::kWrongScene, never
/// traversed as what it is not (check SceneView::two_level() on the host before the
/// launch). What one loop saves, for a kernel of the closest-hit query alone on sm_90
/// (ptxas, CUDA 13.0): uncapped, 128 registers with kEither and 96 with one loop (ptxas'
/// choice varies with the surrounding kernel: 124 for cwbvh_gpu_check's kSingleLevel
/// kernel); capped at 80 (__launch_bounds__(128, 6)), 112 bytes of spills with kEither, 8
/// with kSingleLevel, 32 with kTwoLevel; capped at 64, 440, 112 and 268.
enum class SceneLevels : uint32_t { kEither = 0, kSingleLevel = 1, kTwoLevel = 2 };

/// Traces `ray` through `scene` on the calling thread: the closest hit (kMode = kClosest)
/// or the first one found (kAny). `stack` must be empty; it is left empty unless the
/// status is kStackOverflow or kBadIndex.
template <HitMode kMode = HitMode::kClosest, SceneLevels kLevels = SceneLevels::kEither,
          TriangleTest kTest = TriangleTest::kWatertight, class Stack>
CWBVH_HD CWBVH_INLINE QueryHit intersect(const SceneView& scene, const Ray& ray, Stack& stack) {
    QueryHit q;
    q.hit = make_miss();
    q.record = kInvalidIndex;
    q.instance = kInvalidIndex;
    const TwoLevelScene& s = scene.sections;
    const bool two = scene.two_level();
    if ((kLevels == SceneLevels::kSingleLevel && two) || (kLevels == SceneLevels::kTwoLevel && !two)) {
        q.status = TraceStatus::kWrongScene;
        return q;
    }
    if (kLevels != SceneLevels::kSingleLevel && two)
        q.status = traverse_two_level<kTest, kMode>(s, ray, q.hit, q.instance, stack, nullptr, &q.record);
    else
        q.status = traverse_cwbvh<kTest, kMode>(s.nodes, s.node_count, s.tris, s.tri_count, ray, q.hit, stack,
                                                nullptr, NoPostpone(), s.node_scale, &q.record);
    return q;
}

/// The same with the thread's own LocalStack (64 entries, kCpuStackSize, the CPU
/// reference's): a valid file's trees are at most 32 levels deep, a top-level path and
/// its mesh 32 together (rules 5113 and 6041 of spec/cwbvh-format.md), which the bounds
/// in traverse.h (depth - 1 entries) and traverse_two_level.h (top depth + mesh depth + 1)
/// keep well inside 64.
template <HitMode kMode = HitMode::kClosest, SceneLevels kLevels = SceneLevels::kEither,
          TriangleTest kTest = TriangleTest::kWatertight>
CWBVH_HD CWBVH_INLINE QueryHit intersect(const SceneView& scene, const Ray& ray) {
    LocalStack<kCpuStackSize> stack;
    return intersect<kMode, kLevels, kTest>(scene, ray, stack);
}

/// Whether anything lies on `ray` within [tmin, tmax] (an any-hit query). A ray that
/// cannot be answered exactly (QueryHit::status != kOk) counts as occluded only when
/// a hit was found; use intersect<HitMode::kAny> to see the status.
template <SceneLevels kLevels = SceneLevels::kEither, TriangleTest kTest = TriangleTest::kWatertight>
CWBVH_HD CWBVH_INLINE bool occluded(const SceneView& scene, const Ray& ray) {
    return intersect<HitMode::kAny, kLevels, kTest>(scene, ray).hit.prim != kMissPrim;
}

}  // namespace cwbvh
