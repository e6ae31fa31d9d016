// numpy arrays in: images as cv::Mat views kept alive with their (possibly converted) arrays, and 3-vectors.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <opencv2/core.hpp>

#include "linnet/core/types.h"

namespace linnet::python {

namespace py = pybind11;

/// A uint8 image (H x W gray, or H x W x 3 / 4 BGR(A)) of any memory layout (Fortran order, a cropped view, negative
/// strides), as a cv::Mat over a C-contiguous array that this object keeps alive: `mat` is valid while the ImageView
/// is. UsageError naming `name` for another dtype or shape.
struct ImageView {
  ImageView(const py::array& image, const char* name);
  py::array_t<std::uint8_t, py::array::c_style> array;  // the data `mat` points into (a copy if the input was not
                                                        // C-contiguous)
  cv::Mat mat;
};

/// A 3-vector from any array of 3 numbers (shape (3,), (3, 1), (1, 3)); UsageError naming `name` otherwise.
Vec3 toVec3(const py::object& a, const char* name);

}  // namespace linnet::python
