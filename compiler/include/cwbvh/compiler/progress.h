// How far the running compile phase has come, for cwbvhc's terminal phase line.
// compile() resets the channel at each phase start; the phase code adds to
// `done` in coarse steps from any thread. The counters are only ever written
// by the phases and read by the display: they never influence the output.
#pragma once

#include <atomic>
#include <cstdint>

namespace cwbvh::compiler {

struct Progress {
    /// Units finished in the current phase; reaches `total` when a counted phase ends.
    std::atomic<uint64_t> done{0};
    /// Units of the current phase (triangles for the SBVH, binary nodes for the
    /// collapse, wide nodes for the slots); 0 when the phase is not counted.
    std::atomic<uint64_t> total{0};

    /// Relaxed: the display only needs eventually consistent values, and the
    /// phase's end (joined TBB work) orders every increment before compile() returns.
    void reset(uint64_t units) {
        done.store(0, std::memory_order_relaxed);
        total.store(units, std::memory_order_relaxed);
    }
    void add(uint64_t units) { done.fetch_add(units, std::memory_order_relaxed); }
};

/// Adds to an optional channel (nullptr: no-op).
inline void progress_add(Progress* progress, uint64_t units) {
    if (progress && units) progress->add(units);
}

/// Batches the increments of one thread of a sequential loop: counts locally
/// and publishes every `step` units (and at flush / destruction), so a loop
/// pays one local add per unit and one atomic per step.
class ProgressBatch {
public:
    explicit ProgressBatch(Progress* progress, uint64_t step = 65536) : progress_(progress), step_(step) {}
    ProgressBatch(const ProgressBatch&) = delete;
    ProgressBatch& operator=(const ProgressBatch&) = delete;
    ~ProgressBatch() { flush(); }

    void add(uint64_t units) {
        pending_ += units;
        if (pending_ >= step_) flush();
    }
    void flush() {
        if (progress_ && pending_) {
            progress_->add(pending_);
            published_ += pending_;
        }
        pending_ = 0;
    }
    /// Takes back everything this batch added (a pass that is thrown away and redone).
    void retract() {
        if (progress_ && published_) progress_->done.fetch_sub(published_, std::memory_order_relaxed);
        pending_ = published_ = 0;
    }

private:
    Progress* progress_;
    uint64_t step_;
    uint64_t pending_ = 0, published_ = 0;
};

}  // namespace cwbvh::compiler
