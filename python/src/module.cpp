// The extension module _cwbvh: the C++ half of the `cwbvh` Python package (python/cwbvh/ is the
// public API; this module is its private back end). Error translation lives here: a failed
// cwbvh::Result becomes cwbvh.Error (a RuntimeError) whose str() is the one-line message the
// command-line tools print, with .status (status_name) and .rule (spec rule ID or 0).
#include "common.h"

PYBIND11_MODULE(_cwbvh, m) {
    using namespace cwbvh::python;
    m.doc() = "cwbvh: compile, open and trace .cwbvh files (private back end of the cwbvh package)";
    static py::handle error_type =
        PyErr_NewExceptionWithDoc("cwbvh.Error", "A cwbvh operation failed: str() is its one-line message.",
                                  PyExc_RuntimeError, nullptr);
    m.attr("Error") = error_type;
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) std::rethrow_exception(p);
        } catch (const ResultError& e) {
            py::object err = py::reinterpret_borrow<py::object>(error_type)(e.result().message);
            err.attr("status") = cwbvh::status_name(e.result().status);
            err.attr("rule") = e.result().rule;
            err.attr("message") = e.result().message;
            PyErr_SetObject(error_type.ptr(), err.ptr());
        }
    });
    bind_compile(m);
    bind_scene(m);
    bind_host_trace(m);
    bind_device(m);
    bind_dlpack(m);
}
