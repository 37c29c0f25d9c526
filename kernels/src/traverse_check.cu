// Compile check: instantiates the shared traversal in trivial kernels so nvcc
// proves traverse.h / traverse_bvh2.h build as device code (sm_75, sm_90).
// Not a production kernel (that is a later issue: shared-memory stack,
// postponing, dynamic ray fetch).
#include "cwbvh/kernels/traverse.h"
#include "cwbvh/kernels/traverse_bvh2.h"

namespace cwbvh {

template <TriangleTest kTest, HitMode kMode>
__global__ void check_cwbvh_kernel(const CwbvhNode* nodes, uint32_t node_count, const TriangleRecord* tris,
                                   uint32_t tri_count, const Ray* rays, Hit* hits, uint32_t ray_count) {
    const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= ray_count) return;
    LocalStack<kCpuStackSize> stack;
    TraceCounters c;
    traverse_cwbvh<kTest, kMode>(nodes, node_count, tris, tri_count, rays[i], hits[i], stack, &c);
}

template <TriangleTest kTest, HitMode kMode>
__global__ void check_bvh2_kernel(const Bvh2Node* nodes, uint32_t node_count, const TriangleRecord* tris,
                                  uint32_t tri_count, const Ray* rays, Hit* hits, uint32_t ray_count) {
    const uint32_t i = blockIdx.x * blockDim.x + threadIdx.x;
    if (i >= ray_count) return;
    traverse_bvh2<kTest, kMode>(nodes, node_count, tris, tri_count, rays[i], hits[i]);
}

template __global__ void check_cwbvh_kernel<TriangleTest::kWatertight, HitMode::kClosest>(
    const CwbvhNode*, uint32_t, const TriangleRecord*, uint32_t, const Ray*, Hit*, uint32_t);
template __global__ void check_cwbvh_kernel<TriangleTest::kFast, HitMode::kAny>(
    const CwbvhNode*, uint32_t, const TriangleRecord*, uint32_t, const Ray*, Hit*, uint32_t);
template __global__ void check_bvh2_kernel<TriangleTest::kWatertight, HitMode::kClosest>(
    const Bvh2Node*, uint32_t, const TriangleRecord*, uint32_t, const Ray*, Hit*, uint32_t);
template __global__ void check_bvh2_kernel<TriangleTest::kFast, HitMode::kAny>(
    const Bvh2Node*, uint32_t, const TriangleRecord*, uint32_t, const Ray*, Hit*, uint32_t);

}  // namespace cwbvh
