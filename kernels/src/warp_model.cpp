// Lock-step SIMT warp model (see warp_model.h for the rules it follows).
#include "cwbvh/kernels/warp_model.h"

#include <cstring>

#include <algorithm>
#include <vector>

#include "cwbvh/kernels/bvh2_lane.h"
#include "cwbvh/kernels/cwbvh_lane.h"

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
              const Ray* rays, Hit* hits, const NodeScale& scale, const WarpModelOptions& o, WarpModelStats& s)
        : nodes_(nodes), node_count_(uint32_t(node_count)), tris_(tris), tri_count_(uint32_t(tri_count)),
          rays_(rays), hits_(hits), scale_(scale), o_(o), s_(s) {
        for (Lane& l : lanes_) {
            l.stack.shared_entries = o.shared_stack_entries;
            l.stack.stats = &s;
        }
    }

    /// One scheduling turn: a refill if the warp left its loop, else one iteration.
    /// Returns false when the warp has exited (no rays left for it).
    bool turn(RayCounter& counter) {
        if (need_refill_) {
            write_ended();
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
        bool ended = false;  ///< the ray ended; its hit is written at the next refill (the kernel's state word)
        uint32_t ray_id = 0;
        CwbvhLane<kTest> l{Ray{{0, 0, 0}, 0, {1, 1, 1}, 0}};
        ModelStack stack;
        float u = 0.0f, v = 0.0f;  ///< of the closest hit so far (the kernel's shared s_uv)
        float tlo = 0.0f;          ///< the lane's tlo (CwbvhLane::hit_deferred; the kernel's s_tlo)
        uint32_t nodes = 0, tris = 0;  ///< this ray's node visits and triangle tests (WarpModelStats::worst_ray_*)
    };

    /// TRIS index -> triangle: whole_test's reader (the kernel's reads the read-only cache).
    auto load() const {
        return [t = tris_](uint32_t i) -> const TriangleRecord& { return t[i]; };
    }

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
            lane.l = CwbvhLane<kTest>(ray, scale_);  // the kernel's node tests, fast path included
            lane.tlo = lane.l.tmax;
            lane.stack.clear();
            lane.nodes = lane.tris = 0;
            lane.active = true;
            lane_work += o_.refill_instructions;
        }
    }

    void finish(Lane& lane, TraceStatus status) {
        s_.stack_overflows += status == TraceStatus::kStackOverflow;
        s_.bad_indices += status == TraceStatus::kBadIndex;
        lane.active = false;
        lane.ended = true;
    }

    /// Refill time: the rays that ended get their hits, the deferred ones finished first
    /// (finalize_hit), all lanes together, as in the kernel.
    void write_ended() {
        int finishing = 0;
        for (Lane& lane : lanes_) {
            if (!lane.ended) continue;
            Hit h = make_miss();
            if (lane.l.hit_tri != kNoTriangle) {
                if (lane.l.hit_deferred(lane.tlo)) {
                    // finalize_hit's watertight_finish must give the whole test's t, u, v.
                    TriangleHit whole_th{};
                    const bool whole_hit = whole_test(lane.l, load())(lane.l.hit_tri, lane.l.tmax, whole_th);
                    TriangleHit th;
                    finalize_hit(lane.l, lane.tlo, tris_[lane.l.hit_tri], th);
                    if (!whole_hit || std::memcmp(&whole_th, &th, sizeof th) != 0) ++s_.finalize_failures;
                    lane.u = th.u;
                    lane.v = th.v;
                    ++finishing;
                }
                h = Hit{lane.l.tmax, lane.u, lane.v, tris_[lane.l.hit_tri].prim};  // as the kernel
            }
            hits_[lane.ray_id] = h;
            s_.hits += h.prim != kMissPrim;
            if (uint64_t(lane.nodes) + lane.tris > uint64_t(s_.worst_ray_nodes) + s_.worst_ray_tris) {
                s_.worst_ray_nodes = lane.nodes;
                s_.worst_ray_tris = lane.tris;
                s_.worst_ray_id = lane.ray_id;
            }
            lane.ended = false;
            lane.stack.clear();
        }
        if (finishing) {
            ++s_.warp_finalize_steps;
            s_.lane_finalized += uint64_t(finishing);
        }
    }

    /// Whether the kernel's watertight test, as it is, gets past its two float stages to the
    /// double-precision path (edge signs agree, T not certainly outside [tmin, tmax]).
    static bool passes_float_stages(const Lane& lane, const TriangleRecord& t, float tmax) {
        if constexpr (kTest == TriangleTest::kWatertight) {
            WatertightRay w = lane.l.tri_test.w;
            for (int a = 0; a < 3; ++a) w.org[a] = lane.l.nray.org[a];
            WatertightEdges e;
            return watertight_edges(w, t.v0, t.v1, t.v2, e) &&
                   !watertight_range_miss(w, t.v0, t.v1, t.v2, lane.l.tmin, tmax);
        } else {
            (void)lane, (void)t, (void)tmax;
            return false;
        }
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
                ++lane.nodes;
                s_.lane_fast_node_steps += lane.l.nray.uses_fast_test() ? 1u : 0u;
                visit_node(lane.l, nodes_[index], scale_.frame_word);
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
            int testing = 0, whole_lanes = 0;
            for (Lane& lane : lanes_) {
                if (!(lane.active && lane.l.wants_triangles())) continue;
                if (o_.postpone && should_postpone(wanting, active_before, lane.l.has_node_work(), o_.postpone_percent,
                                               o_.postpone_needs_node_work)) {
                    ++s_.postponed;
                    if (!postpone_triangles(lane.l, lane.stack)) finish(lane, TraceStatus::kStackOverflow);
                    continue;
                }
                const uint32_t ti = next_triangle(lane.l, tri_count_);
                const float tmax_before = lane.l.tmax;
                if (ti == kNoTriangle) {
                    finish(lane, TraceStatus::kBadIndex);
                    continue;
                }
                ++testing;
                ++lane.tris;
                TriangleHit th;
                PrevHit prev_state = PrevHit::kNone;
                TriangleStep step;
                if (o_.defer_hits) {
                    step = test_triangle_deferred(lane.l, lane.tlo, tris_[ti], ti, whole_test(lane.l, load()), th,
                                                  prev_state);
                } else {  // the kernel without the deferral (TraceOptions::defer_hits = false; sm_75)
                    step = test_triangle(lane.l, tris_[ti], ti, th) ? TriangleStep::kExact : TriangleStep::kWholeMiss;
                    lane.tlo = lane.l.tmax;
                }
                if (step == TriangleStep::kExact || prev_state != PrevHit::kNone) {
                    lane.u = th.u;
                    lane.v = th.v;
                }
                s_.lane_prev_finished += prev_state != PrevHit::kNone;
                s_.finalize_failures += prev_state == PrevHit::kFailed;
                s_.lane_deferred_hits += step == TriangleStep::kDeferred;
                // The whole test ran: float could not decide (watertight; the fast test is all
                // float). Without defer_hits: every test that passed the float stages.
                if (kTest == TriangleTest::kWatertight) {
                    if (o_.defer_hits)
                        whole_lanes += step == TriangleStep::kExact || step == TriangleStep::kWholeMiss;
                    else
                        whole_lanes += passes_float_stages(lane, tris_[ti], tmax_before);
                }
                if (kMode == HitMode::kAny && is_hit(step)) finish(lane, TraceStatus::kOk);
            }
            if (whole_lanes) {
                ++s_.warp_whole_rounds;
                s_.lane_whole_tests += uint64_t(whole_lanes);
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
    NodeScale scale_;
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
    const NodeScale scale = o.fast_node_test ? node_scale(nodes, node_count) : NodeScale{};  // as DeviceScene::upload
    return run_warps<W>(ray_count, o, [&](WarpModelStats& s) {
        return W(nodes, node_count, tris, tri_count, rays, hits, scale, o, s);
    });
}

// ---------------------------------------------------------------------------
// BVH2: the Aila-Karras-Laine 2012 kernel (trace_bvh2_persistent) and the 2009
// persistent while-while kernel, both over the lane steps of bvh2_lane.h.
// ---------------------------------------------------------------------------

template <TriangleTest kTest, HitMode kMode>
class Bvh2Warp {
public:
    static constexpr uint32_t kNoRay = 0xFFFFFFFFu;

    Bvh2Warp(const Bvh2Scene& scene, const Ray* rays, Hit* hits, const WarpModelOptions& o, WarpModelStats& s)
        : s_(scene), rays_(rays), hits_(hits), o_(o), st_(s), akl_(o.bvh2_kernel == Bvh2Kernel::kAkl2012) {
        for (uint32_t& i : id_) i = kNoRay;
    }

    bool turn(RayCounter& c) {
        if (need_fetch_) {
            store();
            fetch(c);
            if (busy() == 0) return !exhausted_;
            need_fetch_ = false;
        }
        iterate();
        const int b = busy();
        if (b == 0 || (akl_ && !exhausted_ && b < o_.bvh2_fetch_threshold)) need_fetch_ = true;
        return true;
    }

    double lane_work = 0, issued = 0;

private:
    int busy() const {
        int n = 0;
        for (const auto& l : l_) n += !bvh2_lane_done(l);
        return n;
    }

    /// Step 1 of bvh2_lane.h's warp control: done lanes that hold a ray store it.
    void store() {
        for (int i = 0; i < kLanes; ++i) {
            if (id_[i] == kNoRay || !bvh2_lane_done(l_[i])) continue;
            const Hit h = bvh2_lane_hit(l_[i], m_[i]);
            hits_[id_[i]] = h;
            st_.hits += h.prim != kMissPrim;
            st_.stack_overflows += l_[i].status == TraceStatus::kStackOverflow;
            st_.bad_indices += l_[i].status == TraceStatus::kBadIndex;
            st_.invalid_rays += l_[i].status == TraceStatus::kInvalidRay;
            id_[i] = kNoRay;
        }
    }

    /// Step 2: one atomicAdd for the done lanes; a base past the end exhausts the pool.
    void fetch(RayCounter& c) {
        if (exhausted_) return;
        int need = 0;
        for (const auto& l : l_) need += bvh2_lane_done(l);
        if (need == 0 || (!akl_ && need != kLanes)) return;
        ++st_.refills;
        issued += o_.refill_instructions;
        const size_t base = c.next;
        c.next += size_t(need);
        if (base >= c.count) {
            exhausted_ = true;
            return;
        }
        size_t rank = 0;
        for (int i = 0; i < kLanes; ++i) {
            if (!bvh2_lane_done(l_[i])) continue;
            const size_t r = base + rank++;
            if (r >= c.count) continue;
            id_[i] = uint32_t(r);
            ++st_.rays;
            bvh2_lane_start(l_[i], m_[i], rays_[r], s_);
            lane_work += o_.refill_instructions;
        }
    }

    /// Step 3: node phase (AKL: lanes holding a leaf traverse speculatively), leaf phase.
    void iterate() {
        ++st_.warp_iterations;
        const int b = busy();
        st_.active_lane_iterations += uint64_t(b);
        lane_work += o_.control_instructions * kLanes;
        issued += o_.control_instructions;
        for (;;) {
            int wanting = 0;
            for (const auto& l : l_) wanting += bvh2_lane_in_nodes(l) && !bvh2_lane_has_leaf(l);
            if (wanting == 0) break;
            int n = 0;
            for (int i = 0; i < kLanes; ++i) {
                const bool step = akl_ ? bvh2_lane_in_nodes(l_[i])
                                       : bvh2_lane_in_nodes(l_[i]) && !bvh2_lane_has_leaf(l_[i]);
                if (!step) continue;
                ++n;
                bvh2_lane_node_step(l_[i], m_[i], s_);
                st_.max_stack = std::max<uint64_t>(st_.max_stack, uint64_t(l_[i].sp));
            }
            ++st_.warp_node_steps;
            st_.lane_node_steps += uint64_t(n);
            ++st_.node_lane_hist[n];
            lane_work += o_.bvh2_node_instructions * n;
            issued += o_.bvh2_node_instructions;
        }
        for (;;) {
            int n = 0;
            for (int i = 0; i < kLanes; ++i) {
                if (!bvh2_lane_has_leaf(l_[i])) continue;
                ++n;
                bvh2_lane_triangle_step<kMode>(l_[i], m_[i], s_);
            }
            if (n == 0) break;
            ++st_.warp_tri_steps;
            st_.lane_tri_tests += uint64_t(n);
            ++st_.tri_lane_hist[n];
            lane_work += o_.tri_instructions * n;
            issued += o_.tri_instructions;
        }
    }

    Bvh2Scene s_;
    const Ray* rays_;
    Hit* hits_;
    const WarpModelOptions& o_;
    WarpModelStats& st_;
    bool akl_;
    Bvh2Lane<kTest> l_[kLanes];
    Bvh2LaneMemory m_[kLanes];
    uint32_t id_[kLanes];
    bool need_fetch_ = true;
    bool exhausted_ = false;
};

template <TriangleTest kTest, HitMode kMode>
WarpModelStats model_bvh2(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris, size_t tri_count,
                          const Ray* rays, Hit* hits, size_t ray_count, const WarpModelOptions& o) {
    using W = Bvh2Warp<kTest, kMode>;
    const Bvh2Scene scene = make_bvh2_scene(nodes, uint32_t(node_count), tris, uint32_t(tri_count));
    WarpModelStats s = run_warps<W>(ray_count, o, [&](WarpModelStats& st) { return W(scene, rays, hits, o, st); });
    // The final store of each warp happens when it exits: rays still held are done.
    return s;
}

/// Calls f.template operator()<kTest, kMode>() for the options' test and query.
template <class F>
WarpModelStats dispatch(const WarpModelOptions& o, F f) {
    const bool any = o.mode == HitMode::kAny;
    if (o.test == TriangleTest::kFast)
        return any ? f.template operator()<TriangleTest::kFast, HitMode::kAny>()
                   : f.template operator()<TriangleTest::kFast, HitMode::kClosest>();
    return any ? f.template operator()<TriangleTest::kWatertight, HitMode::kAny>()
               : f.template operator()<TriangleTest::kWatertight, HitMode::kClosest>();
}

}  // namespace

WarpModelStats model_cwbvh_warps(const CwbvhNode* nodes, size_t node_count, const TriangleRecord* tris,
                                 size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                                 const WarpModelOptions& o) {
    return dispatch(o, [&]<TriangleTest kTest, HitMode kMode>() {
        return model_cwbvh<kTest, kMode>(nodes, node_count, tris, tri_count, rays, hits, ray_count, o);
    });
}

WarpModelStats model_bvh2_warps(const Bvh2Node* nodes, size_t node_count, const TriangleRecord* tris,
                                size_t tri_count, const Ray* rays, Hit* hits, size_t ray_count,
                                const WarpModelOptions& o) {
    return dispatch(o, [&]<TriangleTest kTest, HitMode kMode>() {
        return model_bvh2<kTest, kMode>(nodes, node_count, tris, tri_count, rays, hits, ray_count, o);
    });
}

}  // namespace cwbvh
