// Runs the GPU kernels' own bodies (traverse_gpu.h, traverse_gpu_bvh2.h) on the CPU:
// one thread block whose CUDA threads are fibers (ucontext) on one OS thread, with the
// CUDA built-ins these bodies use emulated: a warp vote or shuffle suspends the lane
// until all 32 lanes of its warp have reached it, then every lane reads the combined
// value; __shared__ is one static instance per kernel instantiation; __ldg a plain
// load. Warps take turns, one vote at a time: one legal GPU schedule, and a fixed one
// (runs are deterministic). Issue 18: the developers' machines have no GPU, and the
// kernels' warp-level control (dynamic ray fetch, postponing, the stack, how a ray
// ends) exists once for the device and once in the warp model; this runs the device
// copy itself, so a change to it is tested before a GPU sees it.
//
// What it does not cover: code under `#if defined(__CUDA_ARCH__)` (the product's
// device-only paths: inline PTX for the shared-memory stack and bfind, DPX min/max,
// the 16-byte node loads, the GPU-only float range stage) compiles to its host
// branch here; scripts/gpu-check.sh checks those on a GPU. Timing means nothing here.
// A lane that returns while others of its warp wait at a vote is reported (divergent
// exit: undefined on a GPU).
//
// Include this header before any cwbvh kernel header, in one test source only.
#pragma once

#define CWBVH_WARP_EMULATION 1

#include <ucontext.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <vector>

#if defined(__SANITIZE_ADDRESS__)
#include <sanitizer/common_interface_defs.h>
#endif

#define __device__
#define __host__
#define __forceinline__ inline
// One instance per kernel instantiation, shared by the block's threads: one block at a time.
#define __shared__ static

struct uint3 {
    unsigned x, y, z;
};
struct float2 {
    float x, y;
};
struct alignas(16) float4 {
    float x, y, z, w;
};
inline uint3 threadIdx{0, 0, 0};  // set by the scheduler before it resumes a lane
inline uint3 blockDim{0, 1, 1};

inline float2 make_float2(float x, float y) { return float2{x, y}; }
inline float4 make_float4(float x, float y, float z, float w) { return float4{x, y, z, w}; }
inline float __uint_as_float(unsigned u) {
    float f;
    std::memcpy(&f, &u, sizeof f);
    return f;
}
template <class T>
inline T __ldg(const T* p) {
    T v;
    std::memcpy(&v, p, sizeof v);
    return v;
}
inline int __popc(unsigned x) { return __builtin_popcount(x); }
inline int __ffs(int x) { return __builtin_ffs(x); }
inline unsigned atomicAdd(unsigned* p, unsigned v) { return __atomic_fetch_add(p, v, __ATOMIC_SEQ_CST); }
inline unsigned long long atomicAdd(unsigned long long* p, unsigned long long v) {
    return __atomic_fetch_add(p, v, __ATOMIC_SEQ_CST);
}

namespace cwbvh_emulation {

/// The block's fibers and the scheduler that runs them (one block at a time).
class Block {
public:
    static Block*& current() {
        static Block* b = nullptr;
        return b;
    }

    Block(unsigned threads, std::function<void()> body) : body_(std::move(body)), lanes_(threads) {
        if (threads == 0 || threads % 32 != 0) fail("a block is whole warps of 32 threads");
        for (unsigned t = 0; t < threads; ++t) {
            Lane& l = lanes_[t];
            l.stack.reset(new char[kStackBytes]);
            getcontext(&l.ctx);
            l.ctx.uc_stack.ss_sp = l.stack.get();
            l.ctx.uc_stack.ss_size = kStackBytes;
            l.ctx.uc_link = &scheduler_;
            makecontext(&l.ctx, reinterpret_cast<void (*)()>(&Block::entry), 1, int(t));
        }
        warps_.resize(threads / 32);
    }

    /// Runs every thread to its end; warps take turns, one vote (all 32 lanes) each.
    void run() {
        current() = this;
        blockDim = uint3{unsigned(lanes_.size()), 1, 1};
        for (;;) {
            bool any = false;
            for (size_t w = 0; w < warps_.size(); ++w) {
                int waiting = 0, ended = 0;
                for (unsigned i = 0; i < 32; ++i) {
                    const unsigned t = unsigned(w) * 32 + i;
                    if (lanes_[t].done) {
                        ++ended;
                        continue;
                    }
                    resume(t);
                    if (lanes_[t].done) ++ended; else ++waiting;
                }
                if (waiting != 0 && ended != 0) fail("divergent exit: some lanes of a warp returned while others wait at a vote");
                if (waiting == 32) {
                    std::memcpy(warps_[w].published, warps_[w].slots, sizeof warps_[w].published);
                    any = true;
                }
            }
            if (!any) break;
        }
        current() = nullptr;
    }

    /// Called by a lane at a vote or shuffle: publish `v`, wait for the warp, return
    /// the 32 values every lane published at this point.
    const unsigned long long* meet(unsigned long long v) {
        const unsigned t = threadIdx.x;
        warps_[t / 32].slots[t % 32] = v;
        suspend(t);
        return warps_[t / 32].published;
    }

private:
    static constexpr size_t kStackBytes = 256 * 1024;
    struct Lane {
        ucontext_t ctx;
        std::unique_ptr<char[]> stack;
        bool done = false;
    };
    struct Warp {
        unsigned long long slots[32] = {};
        unsigned long long published[32] = {};
    };

    [[noreturn]] static void fail(const char* what) {
        std::fprintf(stderr, "kernel_emulation: %s\n", what);
        std::abort();
    }

    static void entry(int t) {
        Block* b = current();
#if defined(__SANITIZE_ADDRESS__)
        __sanitizer_finish_switch_fiber(nullptr, &b->main_stack_, &b->main_size_);
#endif
        b->body_();
        b->lanes_[size_t(t)].done = true;
#if defined(__SANITIZE_ADDRESS__)
        __sanitizer_start_switch_fiber(nullptr, b->main_stack_, b->main_size_);  // this fiber ends
#endif
    }  // returns to uc_link: the scheduler

    void resume(unsigned t) {
        threadIdx = uint3{t, 0, 0};
#if defined(__SANITIZE_ADDRESS__)
        void* fake = nullptr;
        __sanitizer_start_switch_fiber(&fake, lanes_[t].stack.get(), kStackBytes);
#endif
        swapcontext(&scheduler_, &lanes_[t].ctx);
#if defined(__SANITIZE_ADDRESS__)
        __sanitizer_finish_switch_fiber(fake, nullptr, nullptr);
#endif
    }

    void suspend(unsigned t) {
#if defined(__SANITIZE_ADDRESS__)
        void* fake = nullptr;
        __sanitizer_start_switch_fiber(&fake, main_stack_, main_size_);
#endif
        swapcontext(&lanes_[t].ctx, &scheduler_);
#if defined(__SANITIZE_ADDRESS__)
        __sanitizer_finish_switch_fiber(fake, &main_stack_, &main_size_);
#endif
        threadIdx = uint3{t, 0, 0};
    }

    std::function<void()> body_;
    std::vector<Lane> lanes_;
    std::vector<Warp> warps_;
    ucontext_t scheduler_{};
    const void* main_stack_ = nullptr;
    size_t main_size_ = 0;
};

/// Runs body() as the `threads` CUDA threads of one block (threads % 32 == 0).
inline void run_block(unsigned threads, const std::function<void()>& body) {
    Block b(threads, body);
    b.run();
}

inline unsigned lane() { return threadIdx.x & 31u; }

}  // namespace cwbvh_emulation

inline unsigned __ballot_sync(unsigned, bool pred) {
    const unsigned long long* v = cwbvh_emulation::Block::current()->meet(pred ? 1u : 0u);
    unsigned b = 0;
    for (unsigned i = 0; i < 32; ++i) b |= unsigned(v[i] & 1u) << i;
    return b;
}
inline bool __any_sync(unsigned mask, bool pred) { return __ballot_sync(mask, pred) != 0; }

/// A shuffle reads the value lane `src` published at the same point.
inline unsigned long long emulated_shuffle(unsigned long long v, unsigned src) {
    return cwbvh_emulation::Block::current()->meet(v)[src & 31u];
}
inline unsigned __shfl_sync(unsigned, unsigned v, int src) { return unsigned(emulated_shuffle(v, unsigned(src))); }
inline int __shfl_sync(unsigned, int v, int src) { return int(unsigned(emulated_shuffle(unsigned(v), unsigned(src)))); }
inline unsigned long long __shfl_down_sync(unsigned, unsigned long long v, unsigned delta) {
    const unsigned me = cwbvh_emulation::lane();
    return emulated_shuffle(v, me + delta < 32 ? me + delta : me);
}
