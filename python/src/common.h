// Shared declarations of the cwbvh Python extension (_cwbvh): the exception that carries a
// cwbvh::Result to Python, and the bind_* functions of the other files (one job each:
// compile.cpp, scene.cpp, host_trace.cpp, device_trace.cpp, dlpack.cpp).
#pragma once

#include <pybind11/pybind11.h>

#include <exception>
#include <string>

#include "cwbvh/format/status.h"

namespace cwbvh::python {

namespace py = pybind11;

/// A failed cwbvh::Result on its way to Python: module.cpp translates it into cwbvh.Error
/// (str() = the one-line message the command-line tools print; .status, .rule).
class ResultError : public std::exception {
public:
    explicit ResultError(Result result) : result_(std::move(result)) {}
    const Result& result() const { return result_; }
    const char* what() const noexcept override { return result_.message.c_str(); }

private:
    Result result_;
};

/// Throws ResultError when `r` failed.
inline void check(Result r) {
    if (!r.ok()) throw ResultError(std::move(r));
}

void bind_compile(py::module_& m);     // compile.cpp
void bind_scene(py::module_& m);       // scene.cpp (open, Scene, info, mesh views, ray helpers)
void bind_host_trace(py::module_& m);  // host_trace.cpp (Scene.trace_host, ray/hit files)
void bind_device(py::module_& m);      // device_trace.cpp (to_device, trace_device, gpu_status)
void bind_dlpack(py::module_& m);      // dlpack.cpp (DLPack capsules in and out)

}  // namespace cwbvh::python
