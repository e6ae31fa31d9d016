// pybind11 module linnet._linnet: thin bindings, plain value types in, results out.
// Each part lives in its own bind_*.cc file.
#include <pybind11/pybind11.h>

namespace py = pybind11;

namespace linnet::python {
void bindSystem(py::module_& m);  // bind_system.cc: Config, System, dataset runs
void bindSim(py::module_& m);     // bind_sim.cc: simulator renderer
void bindLines(py::module_& m);   // bind_lines.cc: line front-end
}  // namespace linnet::python

PYBIND11_MODULE(_linnet, m) {
  m.doc() = "Linnet C++ core";
  m.attr("__version__") = "0.1.0";
  linnet::python::bindSystem(m);
  linnet::python::bindSim(m);
  linnet::python::bindLines(m);
}
