// cwbvhc's terminal phase line (tools/cwbvhc/main.cpp shows it when stderr is a terminal
// and not --quiet): "<phase> ..." when a phase starts, "<phase> <seconds> s" when it ends
// and, once a counted phase has run for more than kDelay, "<phase> <percent>%" every kTick
// while the percentage moves. The clock and the output are passed in, and tick() is public,
// so that tests drive the line through time without sleeping (tests/compiler/progress_test.cpp).
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>

#include "cwbvh/compiler/progress.h"

namespace cwbvh::compiler {

class PhaseLine {
public:
    using Clock = std::chrono::steady_clock;
    using Now = std::function<Clock::time_point()>;
    using Write = std::function<void(const std::string&)>;
    static constexpr std::chrono::milliseconds kDelay{1000}, kTick{200};

    /// `write` gets every piece of the line; `now` tells the time. With `ticker`, a thread
    /// calls tick() every kTick of real time until stop().
    PhaseLine(const Progress& progress, Write write, Now now = Clock::now, bool ticker = true);
    ~PhaseLine() { stop(); }
    PhaseLine(const PhaseLine&) = delete;
    PhaseLine& operator=(const PhaseLine&) = delete;

    /// The PhaseCallback: runs on the thread that runs compile().
    void on_phase(const std::string& phase, bool done, double seconds);
    /// Shows the percentage of the running phase if it is counted, has run longer than
    /// kDelay and moved since it was last shown. Nothing after stop().
    void tick();
    /// Stops and joins the ticker (idempotent); nothing is written after it returns.
    void stop();

private:
    void tick_locked();

    const Progress& progress_;
    Write write_;
    Now now_;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    bool running_ = false;  ///< a phase has started and not ended
    std::string phase_;
    Clock::time_point started_{};
    int shown_ = -1;       ///< percentage on the line now (-1: none)
    std::thread ticker_;   ///< last: starts once everything above is initialised
};

}  // namespace cwbvh::compiler
