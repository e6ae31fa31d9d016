// Bindings: to be filled by the owning module.
#include <pybind11/pybind11.h>

namespace py = pybind11;

namespace linnet::python {
void bindLines(py::module_& m) { (void)m; }
}  // namespace linnet::python
