// cwbvh.compile: the pipeline behind cwbvhc (compile.h), with cwbvhc's options as keyword
// arguments. It runs on a worker thread while the calling thread, without the GIL, waits and
// forwards progress to the optional Python callback (so the callback always runs on the caller's
// thread); an exception the callback raises cancels the compile before its next phase (nothing
// is written). Returns the --stats-json text; __init__.py turns it into a dict.
#include <pybind11/stl.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <new>
#include <thread>

#include "common.h"
#include "cwbvh/compiler/compile.h"
#include "cwbvh/compiler/progress.h"
#include "cwbvh/format/file_io.h"

namespace cwbvh::python {
namespace {

using compiler::CompileOptions;

/// `value` as T, else TypeError "compile: NAME must be EXPECTED, got TYPE" (pybind11's own cast
/// error names neither the option nor what it takes).
template <class T>
T option_as(const py::handle value, const std::string& name, const std::string& expected) {
    try {
        return value.cast<T>();
    } catch (const py::cast_error&) {
        throw py::type_error("compile: " + name + " must be " + expected + ", got " + Py_TYPE(value.ptr())->tp_name);
    }
}

float number_in(const py::handle v, const char* name, float lo, float hi, bool lo_open) {
    const std::string range = std::string("a number in ") + (lo_open ? "(" : "[") + std::to_string(lo).substr(0, 3) +
                              ", " + std::to_string(hi).substr(0, 3) + "]";
    const float x = option_as<float>(v, name, range);
    if (!(lo_open ? x > lo : x >= lo) || !(x <= hi))
        throw py::value_error(std::string("compile: ") + name + " must be " + range);
    return x;
}

/// A yes/no option: True or False (pybind11's bool conversion: also None, numpy bools, numbers).
bool flag(const py::handle v, const char* name) { return option_as<bool>(v, name, "True or False"); }

/// cwbvhc's options by their long names with '_' for '-' (split_alpha for --split-alpha).
void apply_options(const py::dict& options, CompileOptions& o) {
    for (const auto& [key, value] : options) {
        const std::string k = py::str(key);
        if (k == "builder") {
            const std::string v = py::str(value);
            if (v == "sbvh") o.builder = kBuilderSbvh;
            else if (v == "embree") o.builder = kBuilderEmbree;
            else throw py::value_error("unknown builder '" + v + "' (expected sbvh or embree)");
        } else if (k == "collapse") {
            const std::string v = py::str(value);
            if (v == "optimal") o.collapse = kCollapseOptimal;
            else if (v == "greedy") o.collapse = kCollapseGreedy;
            else throw py::value_error("unknown collapse '" + v + "' (expected optimal or greedy)");
        } else if (k == "split_alpha") {
            o.split_alpha = number_in(value, "split_alpha", 0, 1, false);
        } else if (k == "max_reference_growth") {
            o.max_reference_growth = number_in(value, "max_reference_growth", 0, 1, false);
        } else if (k == "collapse_cost_prim") {
            o.collapse_cost_prim = number_in(value, "collapse_cost_prim", 0, 1, true);
        } else if (k == "keep_sbvh") {
            o.keep_sbvh = flag(value, "keep_sbvh");
        } else if (k == "keep_mesh") {
            o.keep_mesh = flag(value, "keep_mesh");
        } else if (k == "verify") {
            o.verify = flag(value, "verify");
        } else if (k == "flatten") {
            o.flatten = flag(value, "flatten");
        } else if (k == "allow_parent_uris") {
            o.allow_parent_uris = flag(value, "allow_parent_uris");
        } else {
            throw py::type_error("compile() got an unexpected option '" + k +
                                 "' (options: builder, collapse, split_alpha, max_reference_growth, "
                                 "collapse_cost_prim, keep_sbvh, keep_mesh, verify, flatten, allow_parent_uris)");
        }
    }
}

struct PhaseEvent {
    std::string phase;
    bool done;
    double seconds;
};

/// Thrown by the worker's PhaseCallback once the Python callback has raised: compile() lets it
/// through (compile.h), so the phases after it never run and nothing is written.
struct Cancelled {};

/// The worker's phase events on their way to the calling thread, which runs the Python callback.
/// A phase start or end waits until the callback has seen it: the callback runs before the phase
/// it announces, so an exception it raises (there, or in a fraction report during the phase
/// before) cancels the compile at that boundary, before the write.
class Relay {
public:
    /// Worker side, the PhaseCallback: hands `e` over and waits; throws Cancelled when the
    /// callback has raised.
    void post(PhaseEvent e) {
        std::unique_lock<std::mutex> lock(mutex_);
        if (cancelled_) throw Cancelled{};
        events_.push_back(std::move(e));
        const uint64_t mine = ++posted_;
        wake_.notify_all();
        wake_.wait(lock, [&] { return delivered_ >= mine || cancelled_; });
        if (cancelled_) throw Cancelled{};
    }
    /// Worker side: compile() has returned (or thrown).
    void finish() {
        const std::lock_guard<std::mutex> lock(mutex_);
        finished_ = true;
        wake_.notify_all();
    }
    /// Calling thread: the events posted so far (waiting at most 0.2 s for one); `end` once the
    /// worker has finished.
    std::deque<PhaseEvent> take(bool& end) {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait_for(lock, std::chrono::milliseconds(200), [&] { return finished_ || !events_.empty(); });
        std::deque<PhaseEvent> batch;
        batch.swap(events_);
        end = finished_;
        return batch;
    }
    /// Calling thread: `n` more events went through the callback; `cancel`: it raised.
    void delivered(size_t n, bool cancel) {
        const std::lock_guard<std::mutex> lock(mutex_);
        delivered_ += n;
        cancelled_ = cancelled_ || cancel;
        wake_.notify_all();
    }

private:
    std::mutex mutex_;
    std::condition_variable wake_;
    std::deque<PhaseEvent> events_;
    uint64_t posted_ = 0, delivered_ = 0;
    bool finished_ = false, cancelled_ = false;
};

/// Runs `work` (compile()) on a worker thread while this thread, without the GIL, forwards its
/// phase starts and ends to `progress` (phase, 0.0, None) / (phase, 1.0, seconds), and every
/// 0.2 s the running counted phase's fraction. The first exception the callback raises stops
/// the reports and the compile (Relay), and is raised here once the worker has stopped.
template <class Work>
Result run_with_progress(const py::object& progress, compiler::Progress& counter, Relay& relay, Work&& work) {
    Result result;
    std::exception_ptr worker_error;
    std::exception_ptr callback_error;
    {
        py::gil_scoped_release release;
        std::thread worker([&] {
            try {
                result = work();
            } catch (const Cancelled&) {
                // the callback's exception (callback_error) is the one raised
            } catch (...) {
                worker_error = std::current_exception();
            }
            relay.finish();
        });
        std::string running;
        uint64_t shown = 0;
        for (bool end = false; !end;) {
            const std::deque<PhaseEvent> batch = relay.take(end);
            if (!progress.is_none() && !callback_error) {
                py::gil_scoped_acquire gil;
                try {
                    for (const PhaseEvent& e : batch) {
                        running = e.done ? "" : e.phase;
                        if (e.done) progress(e.phase, 1.0, e.seconds);
                        else progress(e.phase, 0.0, py::none());
                    }
                    const uint64_t total = counter.total.load(std::memory_order_relaxed);
                    const uint64_t done = counter.done.load(std::memory_order_relaxed);
                    if (!end && !running.empty() && total && done && done != shown) {
                        shown = done;
                        progress(running, std::min(1.0, double(done) / double(total)), py::none());
                    }
                } catch (...) {
                    callback_error = std::current_exception();
                }
            }
            relay.delivered(batch.size(), callback_error != nullptr);
        }
        worker.join();
    }
    if (callback_error) std::rethrow_exception(callback_error);
    if (worker_error) std::rethrow_exception(worker_error);
    return result;
}

std::string compile_py(const std::vector<std::string>& inputs, const std::string& output, int threads,
                       const py::dict& options, const py::object& progress) {
    CompileOptions o;
    o.inputs = inputs;
    o.output = output;
    if (threads < 0 || threads > 4096) throw py::value_error("threads must be None or an integer in [1, 4096]");
    o.threads = threads;
    apply_options(options, o);
    if (o.inputs.empty()) throw py::value_error("no input files");
    if (o.output.empty()) throw py::value_error("no output file");
    // cwbvhc's checks of -o before anything is read, from the same function and with its
    // messages: never overwrite an input (they are not part of compile()).
    check(check_output_path(o.output, o.inputs));

    compiler::CompileStats stats;
    compiler::Progress counter;
    Relay relay;
    const bool report = !progress.is_none();
    compiler::PhaseCallback on_phase;
    if (report)
        on_phase = [&relay](const std::string& phase, bool done, double seconds) {
            relay.post({phase, done, seconds});
        };
    const Result result = run_with_progress(progress, counter, relay, [&] {
        try {
            return compile(o, stats, on_phase, report ? &counter : nullptr);
        } catch (const std::bad_alloc&) {
            return Result::fail(Status::kBadInput, 0, o.inputs.front() + ": out of memory while compiling");
        }
    });
    check(result);
    return compiler::stats_to_json(stats);
}

}  // namespace

void bind_compile(py::module_& m) {
    m.def("compile", &compile_py, py::arg("inputs"), py::arg("output"), py::arg("threads"), py::arg("options"),
          py::arg("progress"));
}

}  // namespace cwbvh::python
