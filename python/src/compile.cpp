// cwbvh.compile: the pipeline behind cwbvhc (compile.h), with cwbvhc's options as keyword
// arguments. It runs on a worker thread while the calling thread, without the GIL, waits and
// forwards progress to the optional Python callback (so the callback always runs on the caller's
// thread). Returns the --stats-json text; __init__.py turns it into a dict.
#include <pybind11/stl.h>

#include <chrono>
#include <condition_variable>
#include <deque>
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

float number_in(const py::handle v, const char* name, float lo, float hi, bool lo_open) {
    const float x = v.cast<float>();
    if (!(lo_open ? x > lo : x >= lo) || !(x <= hi))
        throw py::value_error(std::string(name) + " must be a number in " + (lo_open ? "(" : "[") +
                              std::to_string(lo).substr(0, 3) + ", " + std::to_string(hi).substr(0, 3) + "]");
    return x;
}

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
            o.keep_sbvh = value.cast<bool>();
        } else if (k == "keep_mesh") {
            o.keep_mesh = value.cast<bool>();
        } else if (k == "verify") {
            o.verify = value.cast<bool>();
        } else if (k == "flatten") {
            o.flatten = value.cast<bool>();
        } else if (k == "allow_parent_uris") {
            o.allow_parent_uris = value.cast<bool>();
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
    Result result;
    compiler::Progress counter;
    std::mutex mutex;
    std::condition_variable wake;
    std::deque<PhaseEvent> events;
    bool finished = false;
    const bool report = !progress.is_none();
    compiler::PhaseCallback on_phase;
    if (report) {
        on_phase = [&](const std::string& phase, bool done, double seconds) {
            const std::lock_guard<std::mutex> lock(mutex);
            events.push_back({phase, done, seconds});
            wake.notify_all();
        };
    }
    py::gil_scoped_release release;
    std::thread worker([&] {
        Result r;
        try {
            r = compile(o, stats, on_phase, report ? &counter : nullptr);
        } catch (const std::bad_alloc&) {
            r = Result::fail(Status::kBadInput, 0, o.inputs.front() + ": out of memory while compiling");
        }
        const std::lock_guard<std::mutex> lock(mutex);
        result = std::move(r);
        finished = true;
        wake.notify_all();
    });
    // Forward phase starts and ends, and every 0.2 s the running counted phase's fraction. The
    // first exception the callback raises stops the reports and is raised once compile() ends.
    std::string running;
    uint64_t shown = 0;
    std::exception_ptr callback_error;
    for (;;) {
        std::deque<PhaseEvent> batch;
        bool end = false;
        {
            std::unique_lock<std::mutex> lock(mutex);
            wake.wait_for(lock, std::chrono::milliseconds(200), [&] { return finished || !events.empty(); });
            batch.swap(events);
            end = finished;
        }
        if (report && !callback_error) {
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
        if (end) break;
    }
    worker.join();
    if (callback_error) std::rethrow_exception(callback_error);
    check(result);
    return compiler::stats_to_json(stats);
}

}  // namespace

void bind_compile(py::module_& m) {
    m.def("compile", &compile_py, py::arg("inputs"), py::arg("output"), py::arg("threads"), py::arg("options"),
          py::arg("progress"));
}

}  // namespace cwbvh::python
