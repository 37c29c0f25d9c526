// Two-level CWBVH traversal (format 1.2, issue 19): a top-level CWBVH (TLAS) whose
// leaf "triangles" are instances (INST), each placing one bottom level (a mesh:
// a range of NODE and TRIS) with an affine transform. Written once for the CPU
// reference (cpu_trace.cpp) and the CUDA two-level kernel (kernels_two_level.cu).
//
// One loop, one stack (HIPRT's sentinel; GPU-Raytracer's one loop), reusing
// traverse.h's node step (cwbvh_node_step), leaf-record step (take_leaf_record)
// and triangle step (cwbvh_triangle_step) unchanged:
//   - The top level is walked like a bottom level with the world ray, over TLAS;
//     its leaf records are INST indices.
//   - Entering instance i: the rest of the top-level groups (the node group if it
//     still has node children, then the rest of the instance group) are pushed,
//     then a marker {i, hits = 0}; the ray moves to object space through transform.h
//     (o' = transform_point(W2O, o), d' = transform_vector(W2O, d); tmin and the
//     current tmax unchanged: the map is affine and d' is not renormalized, so t is
//     the caller's ray parameter in both spaces and the closest hit so far still
//     bounds the interval), the per-ray set-up (octant, NodeRay, the triangle test's
//     shear constants) is recomputed for the object-space ray, and the traversal
//     starts at the mesh's root as the node group {node_first, 0x80000000}
//     (absolute NODE/TRIS indices: spec 3.10).
//   - Popping the marker restores the world ray's set-up (recomputed from the
//     world ray) and the top level. A marker is the only stack entry with hits == 0
//     (node groups are pushed with node bits, triangle groups only while non-empty),
//     so nothing else can be taken for one.
// Stack bound: (top depth - 1) + 2 + 1 marker + (mesh depth - 1) entries.
//
// An instance whose object-space ray is not traceable (a component overflowed to
// inf, or the direction underflowed to zero: only for transforms far outside the
// spec's condition bound) is skipped: no hit in it.
//
// Watertightness: within an instance it is that of the triangle test (one object-
// space ray per instance meets every triangle of the mesh); two instances meet
// two different object-space rays, so a seam between two instances is not closed
// by construction (nor in Embree, OptiX or HIPRT).
#pragma once

#include <cstdint>

#include "cwbvh/format/format.h"
#include "cwbvh/format/hostdevice.h"
#include "cwbvh/format/transform.h"
#include "cwbvh/kernels/node_intersect.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/ray.h"
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/triangle_intersect.h"

namespace cwbvh {

/// The sections of a two-level scene, as pointers + counts (host or device memory).
struct TwoLevelScene {
    const CwbvhNode* top_nodes;       ///< TLAS; top_nodes[0] is the root
    uint32_t top_node_count;
    const InstanceRecord* instances;  ///< INST
    uint32_t instance_count;
    const MeshRecord* meshes;         ///< MESH
    uint32_t mesh_count;
    const CwbvhNode* nodes;           ///< NODE (all bottom levels)
    uint32_t node_count;
    const TriangleRecord* tris;       ///< TRIS (all bottom levels)
    uint32_t tri_count;
    /// Constants of the fast node test over NODE and TLAS (node_intersect_fast.h;
    /// DeviceScene::upload: merge_node_scale of both). NodeScale{} (the default, and the
    /// CPU reference): the reference node test everywhere.
    NodeScale node_scale{};
};

/// The ray in the instance's object space (transform.h; tmin and tmax copied).
CWBVH_HD CWBVH_INLINE Ray object_ray(const InstanceRecord& inst, const Ray& world, float tmax) {
    Ray r;
    transform_point(inst.world_to_object, world.org, r.org);
    transform_vector(inst.world_to_object, world.dir, r.dir);
    r.tmin = world.tmin;
    r.tmax = tmax;
    return r;
}

/// Traverse one ray through a two-level scene. hit receives the closest hit
/// (kClosest) or the first found (kAny), or make_miss(); instance receives the
/// INST index of the hit (kInvalidIndex for a miss). hit.prim is the global stored
/// triangle id; t is in the parameter of `ray`. hit_record (optional): the TRIS index of
/// the hit's record (object space of `instance`), kInvalidIndex for a miss.
template <TriangleTest kTest, HitMode kMode, class Stack>
CWBVH_HD CWBVH_INLINE TraceStatus traverse_two_level(const TwoLevelScene& scene, const Ray& ray, Hit& hit,
                                                     uint32_t& instance, Stack& stack,
                                                     TraceCounters* counters = nullptr, uint32_t* hit_record = nullptr) {
    hit = make_miss();
    instance = kInvalidIndex;
    if (hit_record) *hit_record = kInvalidIndex;
    if (!ray_is_traceable(ray) || scene.top_node_count == 0) return TraceStatus::kInvalidRay;
    // The current level's set-up: the world ray's at the top level, the object-space
    // ray's inside an instance (recomputed on entry and on return).
    // The fast node test measures from tmin with its sign bit clear (a -0 tmin is the
    // same closed interval as +0: cwbvh_lane.h).
    const float fast_tmin = ray.tmin == 0.0f ? 0.0f : ray.tmin;
    NodeRay nray = make_node_ray(ray);
    enable_fast_node_test(nray, scene.node_scale, ray.dir, fast_tmin);
    TriangleIntersector<kTest> tri_test(ray);
    const CwbvhNode* nodes = scene.top_nodes;
    uint32_t node_count = scene.top_node_count;
    bool top = true;
    uint32_t current = kInvalidIndex;  // INST index of the instance being traversed
    const float tmin = ray.tmin;
    float tmax = ray.tmax;  // shrinks to the closest hit so far, in both spaces
    uint32_t n_nodes = 0, n_tris = 0;
    TraceStatus status = TraceStatus::kOk;

    StackEntry node_group{0u, 0x80000000u};
    StackEntry tri_group{0u, 0u};
    for (;;) {
        status = cwbvh_node_step(node_group, tri_group, nray, tmin, tmax, nodes, node_count, stack, n_nodes,
                                 scene.node_scale.frame_word);
        if (status != TraceStatus::kOk) break;

        bool done = false;
        if (top) {
            // At most one instance per iteration: entering it replaces both groups.
            while (tri_group.hits != 0) {
                const uint32_t ii = take_leaf_record(tri_group);
                if (ii >= scene.instance_count || scene.instances[ii].mesh >= scene.mesh_count) {
                    status = TraceStatus::kBadIndex;
                    break;
                }
                const InstanceRecord& inst = scene.instances[ii];
                const Ray oray = object_ray(inst, ray, tmax);
                if (!ray_is_traceable(oray)) continue;  // see the file comment
                // Top-level work left over, then the marker (popped first).
                if ((node_group.hits > 0x00FFFFFFu && !stack.push(node_group)) ||
                    (tri_group.hits != 0 && !stack.push(tri_group)) || !stack.push(StackEntry{ii, 0u})) {
                    status = TraceStatus::kStackOverflow;
                    break;
                }
                nray = make_node_ray(oray);
                enable_fast_node_test(nray, scene.node_scale, oray.dir, fast_tmin);
                tri_test = TriangleIntersector<kTest>(oray);
                nodes = scene.nodes;
                node_count = scene.node_count;
                top = false;
                current = ii;
                node_group = StackEntry{scene.meshes[inst.mesh].node_first, 0x80000000u};
                tri_group = StackEntry{0u, 0u};
                break;
            }
        } else {
            while (tri_group.hits != 0) {
                const uint32_t ti = take_leaf_record(tri_group);
                if (ti >= scene.tri_count) {
                    status = TraceStatus::kBadIndex;
                    break;
                }
                ++n_tris;
                if (cwbvh_triangle_step(tri_test, scene.tris[ti], tmin, tmax, hit)) {
                    instance = current;
                    if (hit_record) *hit_record = ti;
                    if (kMode == HitMode::kAny) {
                        done = true;
                        break;
                    }
                }
            }
        }
        if (done || status != TraceStatus::kOk) break;

        if (node_group.hits <= 0x00FFFFFFu) {
            if (stack.empty()) break;
            node_group = stack.pop();
            if (node_group.hits == 0) {
                // The marker: back to the world ray and the top level. The (empty)
                // group makes the next iteration pop again.
                nray = make_node_ray(ray);
                enable_fast_node_test(nray, scene.node_scale, ray.dir, fast_tmin);
                nodes = scene.top_nodes;
                node_count = scene.top_node_count;
                top = true;
            }
        }
    }
    if (counters) {
        counters->nodes = n_nodes;
        counters->triangles = n_tris;
    }
    return status;
}

}  // namespace cwbvh
