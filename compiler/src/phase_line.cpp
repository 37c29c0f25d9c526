// cwbvhc's terminal phase line (phase_line.h). Every write happens under mutex_.
#include "cwbvh/compiler/phase_line.h"

#include <algorithm>
#include <cstdio>
#include <utility>

namespace cwbvh::compiler {

PhaseLine::PhaseLine(const Progress& progress, Write write, Now now, bool ticker)
    : progress_(progress), write_(std::move(write)), now_(std::move(now)) {
    if (ticker)
        ticker_ = std::thread([this] {
            std::unique_lock<std::mutex> lock(mutex_);
            while (!wake_.wait_for(lock, kTick, [this] { return stop_; })) tick_locked();
        });
}

void PhaseLine::on_phase(const std::string& phase, bool done, double seconds) {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (stop_) return;
    char buf[256];
    if (!done) {
        std::snprintf(buf, sizeof buf, "\r\033[K[cwbvhc] %s ...", phase.c_str());
        phase_ = phase;
        started_ = now_();
        running_ = true;
        shown_ = -1;
    } else {
        running_ = false;
        std::snprintf(buf, sizeof buf, "\r\033[K[cwbvhc] %-10s %8.3f s\n", phase.c_str(), seconds);
    }
    write_(buf);
}

void PhaseLine::tick() {
    const std::lock_guard<std::mutex> lock(mutex_);
    if (!stop_) tick_locked();
}

void PhaseLine::tick_locked() {
    if (!running_ || now_() - started_ <= kDelay) return;
    // Relaxed loads: compile() resets the channel before the start callback, which took
    // mutex_, so these see this phase's total (or a later one's); clamp whatever they see.
    const uint64_t total = progress_.total.load(std::memory_order_relaxed);
    if (total == 0) return;  // not counted: the start line stays as it is
    const uint64_t done = progress_.done.load(std::memory_order_relaxed);
    // Rounded down, so 100 % only once all is done.
    const int percent = int(std::clamp(100.0 * double(done) / double(total), 0.0, 100.0));
    if (percent == shown_) return;
    shown_ = percent;
    char buf[256];
    std::snprintf(buf, sizeof buf, "\r\033[K[cwbvhc] %-10s %3d%%", phase_.c_str(), percent);
    write_(buf);
}

void PhaseLine::stop() {
    {
        const std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    if (ticker_.joinable()) ticker_.join();
}

}  // namespace cwbvh::compiler
