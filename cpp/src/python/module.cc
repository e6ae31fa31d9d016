// pybind11 module linnet._linnet: thin bindings, plain value types in, results out.
// Each part lives in its own bind_*.cc file.
#include <pybind11/pybind11.h>

namespace py = pybind11;

namespace linnet::python {
void bindConfig(py::module_& m);  // bind_config.cc: Config
void bindSystem(py::module_& m);  // bind_system.cc: System, FrameResult, exceptions
void bindRun(py::module_& m);     // bind_run.cc: run_euroc, StreamRun, RunSummary
void bindSim(py::module_& m);     // bind_sim.cc: simulator renderer
void bindLines(py::module_& m);   // bind_lines.cc: line front-end
void bindDriver(py::module_& m);  // bind_driver.cc: sensor-module emulator, live runs
}  // namespace linnet::python

PYBIND11_MODULE(_linnet, m) {
  m.doc() = "Linnet C++ core";
  m.attr("__version__") = "0.1.0";
  linnet::python::bindSystem(m);  // first: registers the exception types
  linnet::python::bindConfig(m);
  linnet::python::bindRun(m);
  linnet::python::bindSim(m);
  linnet::python::bindLines(m);
  linnet::python::bindDriver(m);
}
