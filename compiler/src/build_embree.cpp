// Embree 3 adapter (the only file that includes Embree): rtcBuildBVH with
// RTC_BUILD_QUALITY_HIGH (Embree's spatial-split SAH builder), branching
// factor 2, one primitive per leaf, and a splitPrimitive callback that clips
// the triangle itself (clip.cpp, same outward rounding as build_sbvh).
//
// Determinism: Embree's multi-threaded high-quality build is not deterministic
// (Embree issue #20). We run it on an Embree device configured "threads=1"
// inside a one-thread tbb::task_arena, so the result depends only on the
// input; the tree is then renumbered into canonical depth-first order.
// Spatial splits only happen with the callback AND spare primitive capacity
// (Embree silently disables them otherwise): capacity = (1 + growth) * N.
#include <embree3/rtcore.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <tbb/task_arena.h>

#include "cwbvh/compiler/build.h"

namespace cwbvh::compiler {
namespace {

struct ENode {
    bool leaf;
};
struct EInner : ENode {
    Aabb box[2];
    ENode* child[2];
};
struct ELeaf : ENode {
    Aabb box;
    uint32_t prim;
};

struct Context {
    const Scene* scene;
};

Aabb to_aabb(const RTCBounds& b) {
    Aabb a;
    a.lo = {b.lower_x, b.lower_y, b.lower_z};
    a.hi = {b.upper_x, b.upper_y, b.upper_z};
    return a;
}

void* create_node(RTCThreadLocalAllocator alloc, unsigned int child_count, void*) {
    if (child_count != 2) return nullptr;  // maxBranchingFactor = 2
    void* mem = rtcThreadLocalAlloc(alloc, sizeof(EInner), 16);
    EInner* n = new (mem) EInner{};
    n->leaf = false;
    n->child[0] = n->child[1] = nullptr;
    return n;
}

void set_children(void* node, void** children, unsigned int count, void*) {
    EInner* n = static_cast<EInner*>(node);
    for (unsigned i = 0; i < count && i < 2; ++i) n->child[i] = static_cast<ENode*>(children[i]);
}

void set_bounds(void* node, const RTCBounds** bounds, unsigned int count, void*) {
    EInner* n = static_cast<EInner*>(node);
    for (unsigned i = 0; i < count && i < 2; ++i) n->box[i] = to_aabb(*bounds[i]);
}

void* create_leaf(RTCThreadLocalAllocator alloc, const RTCBuildPrimitive* prims, size_t count, void*) {
    // maxLeafSize = 1; should Embree ever hand over more, build a chain of
    // inner nodes over them (median order) so every leaf holds one reference.
    auto leaf = [&](const RTCBuildPrimitive& p) {
        void* mem = rtcThreadLocalAlloc(alloc, sizeof(ELeaf), 16);
        ELeaf* l = new (mem) ELeaf{};
        l->leaf = true;
        l->prim = p.primID;
        l->box.lo = {p.lower_x, p.lower_y, p.lower_z};
        l->box.hi = {p.upper_x, p.upper_y, p.upper_z};
        return static_cast<ENode*>(l);
    };
    if (count == 0) return nullptr;
    ENode* acc = leaf(prims[count - 1]);
    Aabb acc_box = static_cast<ELeaf*>(acc)->box;
    for (size_t i = count - 1; i-- > 0;) {
        void* mem = rtcThreadLocalAlloc(alloc, sizeof(EInner), 16);
        EInner* n = new (mem) EInner{};
        n->leaf = false;
        n->child[0] = leaf(prims[i]);
        n->child[1] = acc;
        n->box[0] = static_cast<ELeaf*>(n->child[0])->box;
        n->box[1] = acc_box;
        for (int j = 0; j < 3; ++j) {
            acc_box.lo[j] = std::min(acc_box.lo[j], n->box[0].lo[j]);
            acc_box.hi[j] = std::max(acc_box.hi[j], n->box[0].hi[j]);
        }
        acc = n;
    }
    return acc;
}

/// Splits a build primitive by clipping its triangle against the plane
/// x[dim] = pos (never its box). A side with no part of the reference gets a
/// degenerate box on the plane inside the primitive's box (Embree expects
/// valid bounds on both sides).
void split_primitive(const RTCBuildPrimitive* prim, unsigned int dim, float pos, RTCBounds* lbounds,
                     RTCBounds* rbounds, void* user) {
    const Context* ctx = static_cast<const Context*>(user);
    const auto tri = ctx->scene->triangle(prim->primID);
    Aabb ref;
    ref.lo = {prim->lower_x, prim->lower_y, prim->lower_z};
    ref.hi = {prim->upper_x, prim->upper_y, prim->upper_z};
    const float inf = std::numeric_limits<float>::infinity();
    const int a = int(dim);
    Aabb l = clip_triangle(tri, a, -inf, pos, ref);
    Aabb r = clip_triangle(tri, a, pos, inf, ref);
    auto on_plane = [&](const Aabb& other) {
        Aabb d = other.empty() ? ref : other;
        d.lo[a] = d.hi[a] = std::clamp(pos, ref.lo[a], ref.hi[a]);
        return d;
    };
    if (l.empty()) l = on_plane(r);
    if (r.empty()) r = on_plane(l);
    *lbounds = RTCBounds{l.lo[0], l.lo[1], l.lo[2], 0.0f, l.hi[0], l.hi[1], l.hi[2], 0.0f};
    *rbounds = RTCBounds{r.lo[0], r.lo[1], r.lo[2], 0.0f, r.hi[0], r.hi[1], r.hi[2], 0.0f};
}

void flatten(const ENode* root, const Aabb& root_box, BinaryBvh& out) {
    struct Item { const ENode* node; Aabb box; uint32_t parent; int side; };
    std::vector<Item> stack{{root, root_box, kInvalidIndex, 0}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        const uint32_t index = uint32_t(out.nodes.size());
        if (it.parent != kInvalidIndex) out.nodes[it.parent].child[it.side] = index;
        BinaryNode bn;
        bn.box = it.box;
        if (it.node->leaf) {
            bn.set_prim(static_cast<const ELeaf*>(it.node)->prim);
            out.nodes.push_back(bn);
            continue;
        }
        out.nodes.push_back(bn);
        const EInner* n = static_cast<const EInner*>(it.node);
        stack.push_back({n->child[1], n->box[1], index, 1});
        stack.push_back({n->child[0], n->box[0], index, 0});
    }
}

}  // namespace

Result build_embree(const Scene& scene, const SbvhConfig& config, BinaryBvh& out) {
    out = BinaryBvh{};
    const size_t tris = scene.triangle_count();
    if (tris == 0) return Result::fail(Status::kInvalidArgument, 0, "build_embree: the scene has no triangles");
    if (tris >= kInvalidIndex / 4) return Result::fail(Status::kInvalidArgument, 0, "build_embree: too many triangles");
    for (size_t i = 0; i < tris; ++i) {
        for (const uint32_t v : scene.indices[i]) {
            if (v >= scene.vertices.size()) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "build_embree: triangle " + std::to_string(i) + " has a vertex index out of range");
            }
            for (const float c : scene.vertices[v]) {
                if (!std::isfinite(c)) {
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "build_embree: triangle " + std::to_string(i) + " has a non-finite vertex");
                }
            }
        }
    }
    const double growth = std::clamp(config.max_reference_growth, 0.0, 8.0);
    const size_t capacity = tris + size_t(growth * double(tris));
    std::vector<RTCBuildPrimitive> prims(std::max<size_t>(capacity, tris));
    Aabb root;
    for (size_t i = 0; i < tris; ++i) {
        Aabb b;
        for (const Vec3& v : scene.triangle(i)) b.grow(v);
        root.grow(b.lo);
        root.grow(b.hi);
        prims[i] = RTCBuildPrimitive{b.lo[0], b.lo[1], b.lo[2], 0u, b.hi[0], b.hi[1], b.hi[2], uint32_t(i)};
    }

    bool ok = false;
    std::string error;
    auto run = [&] {
        RTCDevice device = rtcNewDevice("threads=1");
        if (!device) {
            error = "build_embree: rtcNewDevice failed";
            return;
        }
        RTCBVH bvh = rtcNewBVH(device);
        Context ctx{&scene};
        RTCBuildArguments args = rtcDefaultBuildArguments();
        args.buildQuality = RTC_BUILD_QUALITY_HIGH;
        args.maxBranchingFactor = 2;
        args.maxDepth = 1024;
        args.sahBlockSize = 1;
        args.minLeafSize = 1;
        args.maxLeafSize = 1;
        args.traversalCost = config.cost_traversal;
        args.intersectionCost = config.cost_intersect;
        args.bvh = bvh;
        args.primitives = prims.data();
        args.primitiveCount = tris;
        args.primitiveArrayCapacity = prims.size();
        args.createNode = create_node;
        args.setNodeChildren = set_children;
        args.setNodeBounds = set_bounds;
        args.createLeaf = create_leaf;
        args.splitPrimitive = split_primitive;
        args.userPtr = &ctx;
        const ENode* root_node = static_cast<const ENode*>(rtcBuildBVH(&args));
        const RTCError err = rtcGetDeviceError(device);
        if (err != RTC_ERROR_NONE || !root_node) {
            error = "build_embree: rtcBuildBVH failed (RTCError " + std::to_string(int(err)) + ")";
        } else {
            flatten(root_node, root, out);
            // A tree over one primitive is a single leaf: its box is the
            // triangle's box, which is `root` already.
            ok = true;
        }
        rtcReleaseBVH(bvh);  // frees the nodes (thread-local allocator memory)
        rtcReleaseDevice(device);
    };
    // One TBB thread as well: Embree's TBB tasking runs in the caller's arena.
    tbb::task_arena arena(1);
    arena.execute(run);
    if (!ok) return Result::fail(Status::kInternal, 0, error);
    // Root box: the union of the children (Embree gives child bounds only).
    if (!out.nodes[0].is_leaf()) {
        Aabb b = out.nodes[out.nodes[0].child[0]].box;
        const Aabb& c = out.nodes[out.nodes[0].child[1]].box;
        for (int j = 0; j < 3; ++j) {
            b.lo[j] = std::min(b.lo[j], c.lo[j]);
            b.hi[j] = std::max(b.hi[j], c.hi[j]);
        }
        out.nodes[0].box = b;
    }
    uint64_t leaves = 0;
    for (const BinaryNode& n : out.nodes) leaves += n.is_leaf() ? 1 : 0;
    out.references = leaves;
    // Embree does not report its split kinds. We count as spatial splits the
    // internal nodes where some triangle has references in both subtrees
    // (the lowest common ancestor of two consecutive leaves of a triangle).
    std::vector<uint32_t> parent(out.nodes.size(), kInvalidIndex), depth(out.nodes.size(), 0);
    std::vector<uint32_t> last_leaf(tris, kInvalidIndex);
    std::vector<uint8_t> spatial(out.nodes.size(), 0);
    for (uint32_t i = 0; i < out.nodes.size(); ++i) {
        const BinaryNode& n = out.nodes[i];
        if (!n.is_leaf()) {
            for (const uint32_t c : n.child) { parent[c] = i; depth[c] = depth[i] + 1; }
            continue;
        }
        uint32_t& prev = last_leaf[n.prim()];
        if (prev != kInvalidIndex) {
            uint32_t x = prev, y = i;
            while (x != y) {
                if (depth[x] >= depth[y]) x = parent[x]; else y = parent[y];
            }
            spatial[x] = 1;
        }
        prev = i;
    }
    out.spatial_splits = 0;
    for (const uint8_t f : spatial) out.spatial_splits += f;
    out.object_splits = (leaves - 1) - out.spatial_splits;
    return Result::success();
}

}  // namespace cwbvh::compiler
