#include "bind_images.h"

#include <string>

#include "linnet/core/error.h"

namespace linnet::python {

// The System copies the pixels it keeps and never writes to them, so read-only arrays are fine (const_cast below).
ImageView::ImageView(const py::array& image, const char* name) {
  if (!py::isinstance<py::array>(image))
    throw UsageError(std::string(name) + " image must be a numpy uint8 array, got " +
                     py::str(py::type::of(image).attr("__name__")).cast<std::string>());
  if (!py::isinstance<py::array_t<std::uint8_t>>(image))
    throw UsageError(std::string(name) + " image must be a numpy uint8 array, got dtype " +
                     py::str(image.dtype()).cast<std::string>());
  // ensure() returns the array itself when it is already C-contiguous uint8, else a C-contiguous copy; either way
  // `array` owns a reference, so the pixels outlive this call.
  array = py::array_t<std::uint8_t, py::array::c_style>::ensure(image);
  if (!array) throw UsageError(std::string(name) + " image: cannot read the array");
  const int rows = array.ndim() >= 1 ? static_cast<int>(array.shape(0)) : 0;
  const int cols = array.ndim() >= 2 ? static_cast<int>(array.shape(1)) : 0;
  if (array.ndim() == 2) {
    mat = cv::Mat(rows, cols, CV_8UC1, const_cast<std::uint8_t*>(array.data()));
  } else if (array.ndim() == 3 && (array.shape(2) == 3 || array.shape(2) == 4)) {
    mat = cv::Mat(rows, cols, CV_8UC(static_cast<int>(array.shape(2))),
                  const_cast<std::uint8_t*>(array.data()));
  } else {
    throw UsageError(std::string(name) + " image must be H x W (gray) or H x W x 3 (BGR), got " +
                     std::to_string(array.ndim()) + " dimensions");
  }
}

Vec3 toVec3(const py::object& a, const char* name) {
  const auto v = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!v) throw UsageError(std::string(name) + " must be an array of 3 numbers");
  if (v.size() != 3)
    throw UsageError(std::string(name) + " must have 3 elements, got " + std::to_string(v.size()));
  const double* d = v.data();
  return Vec3(d[0], d[1], d[2]);
}

}  // namespace linnet::python
