// Python callables called from C++ threads: kept alive by a shared holder whose last owner deletes the function with
// the GIL, and invoked with the GIL.
#pragma once

#include <pybind11/pybind11.h>

#include <functional>
#include <memory>
#include <optional>

namespace linnet::python {

namespace py = pybind11;

/// `f` held so that whichever thread drops the last copy deletes it with the GIL.
inline std::shared_ptr<py::function> holdFunction(py::function f) {
  return std::shared_ptr<py::function>(new py::function(std::move(f)), [](py::function* p) {
    py::gil_scoped_acquire gil;
    delete p;
  });
}

/// A C++ callback that calls `f` (if given) with the GIL; empty when `f` is not given.
template <class... Args>
std::function<void(Args...)> withGil(const std::optional<py::function>& f) {
  if (!f) return {};
  auto holder = holdFunction(*f);
  return [holder](Args... args) {
    py::gil_scoped_acquire gil;
    (*holder)(args...);
  };
}

}  // namespace linnet::python
