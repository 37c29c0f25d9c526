// Lock-step SIMT warp model (see warp_model.h for the rules it follows).
#include "cwbvh/warp_model.h"

#include <algorithm>
#include <vector>

#include "cwbvh/cwbvh_lane.h"
#include "cwbvh/traverse_bvh2.h"

namespace cwbvh {
namespace {

constexpr int kLanes = 32;

/// GpuStack's capacity and overflow rule, counting the pushes that would spill
/// from shared to local memory on the GPU.
struct ModelStack {
    StackEntry entries[kGpuStackEntries];
    int size = 0;
    int shared_entries = kGpuSharedStackEntries;
    WarpModelStats* stats = nullptr;

    bool push(StackEntry e) {
        if (size >= kGpuStackEntries) return false;
        if (size >= shared_entries) ++stats->spilled_pushes;
        entries[size++] = e;
        stats->max_stack = std::max<uint64_t>(stats->max_stack, uint64_t(size));
        return true;
    }
    bool empty() const { return size == 0; }
    StackEntry pop() { return entries[--size]; }
    void clear() { size = 0; }
};

/// Shared ray counter of all simulated warps.
struct RayCounter {
    size_t next = 0;
    size_t count = 0;
};

// ---------------------------------------------------------------------------
// CWBVH
// ---------------------------------------------------------------------------

template <TriangleTest kTest, HitMode kMode>
class CwbvhWarp {
public:
    CwbvhWarp(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count,
              const Ray* rays, Hit* hits, const WarpModelOptions& o, WarpModelStats& s)
        : nodes_(nodes), node_count_(uint32_t(node_count)), tris_(tris), tri_count_(uint32_t(tri_count)),
          rays_(rays), hits_(hits), o_(o), s_(s) {
        for (Lane& l : lanes_) {
            l.stack.shared_entries = o.shared_stack_entries;
            l.stack.stats = &s;
        }
    }

    /// One scheduling turn: a refill if the warp left its loop, else one iteration.
    /// Returns false when the warp has exited (no rays left for it).
    bool turn(RayCounter& counter) {
        if (need_refill_) {
            refill(counter);
            if (active_count() == 0) return !exhausted_;  // all fetched rays invalid: fetch again
            need_refill_ = false;
            lost_ = 0;
        }
        iterate();
        const int act = active_count();
        if (act == 0) {
            need_refill_ = true;
            return true;
        }
        lost_ = update_lost_work(lost_, act, o_.fetch_nd);
        if (o_.dynamic_fetch && !exhausted_ && lost_ >= o_.fetch_nw) need_refill_ = true;
        return true;
    }

    double lane_work = 0, issued = 0;  // for the lanes-per-instruction estimate

private:
    struct Lane {
        bool active = false;
        uint32_t ray_id = 0;
        CwbvhLane<kTest> l{Ray{{0, 0, 0}, 0, {1, 1, 1}, 0}};
        ModelStack stack;
    };

    int active_count() const {
        int n = 0;
        for (const Lane& l : lanes_) n += l.active;
        return n;
    }

    void refill(RayCounter& c) {
        if (exhausted_) return;
        int want = 0;
        for (const Lane& l : lanes_) want += !l.active;
        if (want == 0) return;
        ++s_.refills;
        issued += o_.refill_instructions;
        const size_t base = c.next;
        c.next += size_t(want);
        if (base + size_t(want) >= c.count) exhausted_ = true;
        size_t id = base;
        for (Lane& lane : lanes_) {
            if (lane.active) continue;
            const size_t my = id++;
            if (my >= c.count) continue;
            const Ray& ray = rays_[my];
            lane.ray_id = uint32_t(my);
            ++s_.rays;
            if (!ray_is_traceable(ray) || node_count_ == 0) {
                hits_[my] = make_miss();
                ++s_.invalid_rays;
                continue;
            }
            lane.l = CwbvhLane<kTest>(ray);
            lane.stack.clear();
            lane.active = true;
            lane_work += o_.refill_instructions;
        }
    }

    void finish(Lane& lane, TraceStatus status) {
        Hit h = make_miss();
        if (status == TraceStatus::kOk && lane.l.hit_tri != kNoTriangle) h = lane_hit(lane.l, tris_[lane.l.hit_tri]);
        hits_[lane.ray_id] = h;
        s_.hits += h.prim != kMissPrim;
        s_.stack_overflows += status == TraceStatus::kStackOverflow;
        s_.bad_indices += status == TraceStatus::kBadIndex;
        lane.active = false;
        lane.stack.clear();
    }

    void iterate() {
        ++s_.warp_iterations;
        const int active_lanes = active_count();
        s_.active_lane_iterations += uint64_t(active_lanes);
        lane_work += o_.control_instructions * kLanes;
        issued += o_.control_instructions;

        // (a) node phase
        int visiting = 0;
        for (Lane& lane : lanes_) {
            if (!lane.active) continue;
            uint32_t index = 0;
            const NodeStep step = next_node(lane.l, lane.stack, node_count_, index);
            if (step == NodeStep::kVisit) {
                ++visiting;
                visit_node(lane.l, nodes_[index]);
            } else if (step == NodeStep::kOverflow) {
                finish(lane, TraceStatus::kStackOverflow);
            } else if (step == NodeStep::kBadIndex) {
                finish(lane, TraceStatus::kBadIndex);
            }
        }
        if (visiting) {
            ++s_.warp_node_steps;
            s_.lane_node_steps += uint64_t(visiting);
            ++s_.node_lane_hist[visiting];
            lane_work += o_.node_instructions * visiting;
            issued += o_.node_instructions;
        }

        // (b) triangle rounds; the active count is taken before them, as in the kernel
        const int active_before = active_count();
        for (;;) {
            int wanting = 0;
            for (const Lane& lane : lanes_) wanting += lane.active && lane.l.wants_triangles();
            if (wanting == 0) break;
            int testing = 0;
            for (Lane& lane : lanes_) {
                if (!(lane.active && lane.l.wants_triangles())) continue;
                if (o_.postpone && should_postpone(wanting, active_before, lane.l.has_node_work(), o_.postpone_percent,
                                               o_.postpone_needs_node_work)) {
                    ++s_.postponed;
                    if (!postpone_triangles(lane.l, lane.stack)) finish(lane, TraceStatus::kStackOverflow);
                    continue;
                }
                const uint32_t ti = next_triangle(lane.l, tri_count_);
                if (ti == kNoTriangle) {
                    finish(lane, TraceStatus::kBadIndex);
                    continue;
                }
                ++testing;
                if (test_triangle(lane.l, tris_[ti], ti) && kMode == HitMode::kAny) finish(lane, TraceStatus::kOk);
            }
            if (testing) {
                ++s_.warp_tri_steps;
                s_.lane_tri_tests += uint64_t(testing);
                ++s_.tri_lane_hist[testing];
                lane_work += o_.tri_instructions * testing;
                issued += o_.tri_instructions;
            }
        }

        // (c) pop
        for (Lane& lane : lanes_)
            if (lane.active && pop_if_idle(lane.l, lane.stack)) finish(lane, TraceStatus::kOk);
    }

    const CwbvhNode* nodes_;
    uint32_t node_count_;
    const TriangleRecord* tris_;
    uint32_t tri_count_;
    const Ray* rays_;
    Hit* hits_;
    const WarpModelOptions& o_;
    WarpModelStats& s_;
    Lane lanes_[kLanes];
    bool need_refill_ = true;
    bool exhausted_ = false;
    int lost_ = 0;
};

template <class Warp, class Make>
WarpModelStats run_warps(size_t ray_count, const WarpModelOptions& o, Make make) {
    WarpModelStats s;
    RayCounter counter;
    counter.count = ray_count;
    std::vector<Warp> warps;
    const size_t n_warps = std::max<size_t>(1, std::min<size_t>(o.warps, (ray_count + kLanes - 1) / kLanes));
    warps.reserve(n_warps);
    for (size_t i = 0; i < n_warps; ++i) warps.push_back(make(s));
    std::vector<size_t> live(n_warps);
    for (size_t i = 0; i < n_warps; ++i) live[i] = i;
    while (!live.empty()) {
        size_t kept = 0;
        for (size_t i : live)
            if (warps[i].turn(counter)) live[kept++] = i;
        live.resize(kept);
    }
    double work = 0, issued = 0;
    for (const Warp& w : warps) {
        work += w.lane_work;
        issued += w.issued;
    }
    s.estimated_lanes_per_instruction = issued > 0 ? work / issued : 0;
    s.estimated_instructions = issued;
    return s;
}

template <TriangleTest kTest, HitMode kMode>
WarpModelStats model_cwbvh(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count,
                           const Ray* rays, Hit* hits, size_t ray_count, const WarpModelOptions& o) {
    using W = CwbvhWarp<kTest, kMode>;
    return run_warps<W>(ray_count, o, [&](WarpModelStats& s) {
        return W(nodes, node_count, tris, tri_count, rays, hits, o, s);
    });
}

// ---------------------------------------------------------------------------
// BVH2, the 2009 persistent while-while kernel
// ---------------------------------------------------------------------------

template <TriangleTest kTest, HitMode kMode>
class Bvh2Warp {
public:
    static constexpr int32_t kSentinel = 0x76543210;
    static constexpr int kStack = 64;

    Bvh2Warp(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count, const Ray* rays,
             Hit* hits, const WarpModelOptions& o, WarpModelStats& s)
        : nodes_(nodes), node_count_(uint32_t(node_count)), tris_(tris), tri_count_(uint32_t(tri_count)),
          rays_(rays), hits_(hits), o_(o), s_(s) {}

    bool turn(RayCounter& c) {
        bool any = false;
        for (const Lane& l : lanes_) any |= l.active;
        if (!any) {
            if (c.next >= c.count) return false;
            fetch(c);
            return true;
        }
        trip();
        return true;
    }

    double lane_work = 0, issued = 0;

private:
    struct Lane {
        bool active = false;
        uint32_t ray_id = 0;
        Bvh2Ray bray{};
        TriangleIntersector<kTest> tri_test{Ray{{0, 0, 0}, 0, {1, 1, 1}, 0}};
        float tmin = 0, tmax = 0;
        Hit hit{};
        int32_t node = kSentinel;
        int32_t stack[kStack];
        int sp = 0;
    };

    void fetch(RayCounter& c) {
        ++s_.refills;
        issued += o_.refill_instructions;
        const size_t base = c.next;
        c.next += kLanes;
        for (int i = 0; i < kLanes; ++i) {
            Lane& l = lanes_[i];
            if (base + size_t(i) >= c.count) continue;
            const uint32_t id = uint32_t(base + size_t(i));
            const Ray& r = rays_[id];
            ++s_.rays;
            l.ray_id = id;
            if (!ray_is_traceable(r) || node_count_ == 0) {
                hits_[id] = make_miss();
                ++s_.invalid_rays;
                continue;
            }
            l.bray = make_bvh2_ray(r);
            l.tri_test = TriangleIntersector<kTest>(r);
            l.tmin = r.tmin;
            l.tmax = r.tmax;
            l.hit = make_miss();
            l.node = 0;
            l.sp = 0;
            l.active = true;
            lane_work += o_.refill_instructions;
        }
    }

    void finish(Lane& l, TraceStatus status) {
        hits_[l.ray_id] = status == TraceStatus::kOk ? l.hit : make_miss();
        s_.hits += status == TraceStatus::kOk && l.hit.prim != kMissPrim;
        s_.stack_overflows += status == TraceStatus::kStackOverflow;
        s_.bad_indices += status == TraceStatus::kBadIndex;
        l.active = false;
    }

    int32_t pop(Lane& l) { return l.sp > 0 ? l.stack[--l.sp] : kSentinel; }

    static bool in_node_loop(const Lane& l) { return l.active && l.node >= 0 && l.node != kSentinel; }
    static bool in_leaf_loop(const Lane& l) { return l.active && l.node < 0; }

    void node_step(Lane& l) {
        if (uint32_t(l.node) >= node_count_) return finish(l, TraceStatus::kBadIndex);
        const Bvh2Node& n = nodes_[l.node];
        const float lo0[3] = {n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, hi0[3] = {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z};
        const float lo1[3] = {n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, hi1[3] = {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z};
        float t0 = 0, t1 = 0;
        const bool h0 = intersect_box_robust(l.bray, lo0, hi0, l.tmin, l.tmax, t0);
        const bool h1 = intersect_box_robust(l.bray, lo1, hi1, l.tmin, l.tmax, t1);
        if (!h0 && !h1) {
            l.node = pop(l);
            return;
        }
        int near_c = h0 ? 0 : 1;
        if (h0 && h1) {
            if (t1 < t0) near_c = 1;
            if (l.sp >= kStack) return finish(l, TraceStatus::kStackOverflow);
            if (l.sp >= o_.shared_stack_entries) ++s_.spilled_pushes;
            l.stack[l.sp++] = n.child[1 - near_c];
            s_.max_stack = std::max<uint64_t>(s_.max_stack, uint64_t(l.sp));
        }
        l.node = n.child[near_c];
    }

    /// The 2009 kernel's leaves hold one triangle each (legacy BVH2 section).
    void leaf_step(Lane& l) {
        const uint32_t ti = uint32_t(~l.node);
        if (ti >= tri_count_) return finish(l, TraceStatus::kBadIndex);
        TriangleHit th;
        if (l.tri_test(tris_[ti], l.tmin, l.tmax, th)) {
            l.tmax = th.t;
            l.hit = Hit{th.t, th.u, th.v, tris_[ti].prim};
            if (kMode == HitMode::kAny) return finish(l, TraceStatus::kOk);
        }
        l.node = pop(l);
    }

    void trip() {
        ++s_.warp_iterations;
        int act = 0;
        for (const Lane& l : lanes_) act += l.active;
        s_.active_lane_iterations += uint64_t(act);
        lane_work += o_.control_instructions * kLanes;
        issued += o_.control_instructions;
        // Node loop: runs while any lane is in it.
        for (;;) {
            int n = 0;
            for (Lane& l : lanes_)
                if (in_node_loop(l)) ++n, node_step(l);
            if (n == 0) break;
            ++s_.warp_node_steps;
            s_.lane_node_steps += uint64_t(n);
            ++s_.node_lane_hist[n];
            lane_work += o_.bvh2_node_instructions * n;
            issued += o_.bvh2_node_instructions;
        }
        // Leaf loop: runs while any lane is in it.
        for (;;) {
            int n = 0;
            for (Lane& l : lanes_)
                if (in_leaf_loop(l)) ++n, leaf_step(l);
            if (n == 0) break;
            ++s_.warp_tri_steps;
            s_.lane_tri_tests += uint64_t(n);
            ++s_.tri_lane_hist[n];
            lane_work += o_.tri_instructions * n;
            issued += o_.tri_instructions;
        }
        for (Lane& l : lanes_)
            if (l.active && l.node == kSentinel) finish(l, TraceStatus::kOk);
    }

    const Bvh2Node* nodes_;
    uint32_t node_count_;
    const TriangleRecord* tris_;
    uint32_t tri_count_;
    const Ray* rays_;
    Hit* hits_;
    const WarpModelOptions& o_;
    WarpModelStats& s_;
    Lane lanes_[kLanes];
};

template <TriangleTest kTest, HitMode kMode>
WarpModelStats model_bvh2(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count,
                          const Ray* rays, Hit* hits, size_t ray_count, const WarpModelOptions& o) {
    using W = Bvh2Warp<kTest, kMode>;
    return run_warps<W>(ray_count, o, [&](WarpModelStats& s) {
        return W(nodes, node_count, tris, tri_count, rays, hits, o, s);
    });
}

}  // namespace

WarpModelStats model_cwbvh_warps(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris,
                                 size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                                 const WarpModelOptions& o) {
    const bool any = o.mode == HitMode::kAny;
    if (o.test == TriangleTest::kFast) {
        return any ? model_cwbvh<TriangleTest::kFast, HitMode::kAny>(nodes, node_count, tris, tri_count, rays, hits,
                                                                      ray_count, o)
                   : model_cwbvh<TriangleTest::kFast, HitMode::kClosest>(nodes, node_count, tris, tri_count, rays,
                                                                          hits, ray_count, o);
    }
    return any ? model_cwbvh<TriangleTest::kWatertight, HitMode::kAny>(nodes, node_count, tris, tri_count, rays, hits,
                                                                        ray_count, o)
               : model_cwbvh<TriangleTest::kWatertight, HitMode::kClosest>(nodes, node_count, tris, tri_count, rays,
                                                                            hits, ray_count, o);
}

WarpModelStats model_bvh2_2009_warps(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris,
                                     size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                                     const WarpModelOptions& o) {
    const bool any = o.mode == HitMode::kAny;
    if (o.test == TriangleTest::kFast) {
        return any ? model_bvh2<TriangleTest::kFast, HitMode::kAny>(nodes, node_count, tris, tri_count, rays, hits,
                                                                     ray_count, o)
                   : model_bvh2<TriangleTest::kFast, HitMode::kClosest>(nodes, node_count, tris, tri_count, rays,
                                                                         hits, ray_count, o);
    }
    return any ? model_bvh2<TriangleTest::kWatertight, HitMode::kAny>(nodes, node_count, tris, tri_count, rays, hits,
                                                                       ray_count, o)
               : model_bvh2<TriangleTest::kWatertight, HitMode::kClosest>(nodes, node_count, tris, tri_count, rays,
                                                                           hits, ray_count, o);
}

}  // namespace cwbvh
