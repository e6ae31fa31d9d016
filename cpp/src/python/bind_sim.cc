// Bindings of the simulator's renderer (linnet::sim): Scene (textured quads) and Renderer (one camera).
// Plain values in (numpy arrays, lists, floats), numpy images out. Rendering releases the GIL.
#include <cstring>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "linnet/core/error.h"
#include "linnet/sim/renderer.h"

namespace py = pybind11;

namespace linnet::python {
namespace {

using F64Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

Vec3 toVec3(const F64Array& a, const char* name) {
  if (a.size() != 3) throw InputError(std::string("sim: '") + name + "' must have 3 elements");
  const double* d = a.data();
  return Vec3(d[0], d[1], d[2]);
}

Pose toPose(const F64Array& T) {
  if (T.ndim() != 2 || T.shape(0) != 4 || T.shape(1) != 4) throw InputError("sim: a pose must be a 4x4 matrix T_W_C");
  Mat4 M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = T.at(r, c);
  return Pose::fromMatrix(M);
}

template <class T>
py::array_t<T> toNumpy(const cv::Mat& m) {
  py::array_t<T> out({m.rows, m.cols});
  for (int r = 0; r < m.rows; ++r)
    std::memcpy(out.mutable_data(r, 0), m.ptr<T>(r), sizeof(T) * static_cast<std::size_t>(m.cols));
  return out;
}

cv::Mat fromNumpyU8(const py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>& a) {
  if (a.ndim() != 2) throw InputError("sim: a texture must be a 2-D uint8 array");
  cv::Mat m(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1);
  std::memcpy(m.data, a.data(), static_cast<std::size_t>(a.size()));
  return m;
}

}  // namespace

void bindSim(py::module_& m) {
  auto sim = m.def_submodule("sim", "Simulator renderer: textured planar quads -> distorted grey images");

  py::class_<sim::Scene>(sim, "Scene", "Textured parallelograms X(s,t) = origin + s*axis_u + t*axis_v in W.")
      .def(py::init<>())
      .def(
          "add_texture",
          [](sim::Scene& s, const py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>& img) {
            return s.addTexture(fromNumpyU8(img));
          },
          py::arg("image"), "Adds a uint8 (rows, cols) texture; returns its index.")
      .def(
          "add_quad",
          [](sim::Scene& s, const F64Array& origin, const F64Array& axis_u, const F64Array& axis_v, int texture,
             double shade) {
            sim::Quad q;
            q.origin = toVec3(origin, "origin");
            q.axis_u = toVec3(axis_u, "axis_u");
            q.axis_v = toVec3(axis_v, "axis_v");
            q.texture = texture;
            q.shade = shade;
            s.addQuad(q);
          },
          py::arg("origin"), py::arg("axis_u"), py::arg("axis_v"), py::arg("texture"), py::arg("shade") = 1.0)
      .def_property_readonly("num_quads", [](const sim::Scene& s) { return s.quads().size(); })
      .def_property_readonly("num_textures", [](const sim::Scene& s) { return s.textures().size(); });

  py::class_<sim::Renderer>(sim, "Renderer", "Renders one calibrated camera (pinhole + radtan/equidistant/none).")
      .def(py::init([](int width, int height, const std::vector<double>& intrinsics, const std::string& distortion,
                       const std::vector<double>& coeffs, int supersample, double read_noise, double shot_noise,
                       double vignetting, double background, double near_m, double lod_bias) {
             CameraCalibration calib;
             calib.width = width;
             calib.height = height;
             if (intrinsics.size() != 4) throw ConfigError("sim.Renderer: intrinsics must be [fx, fy, cx, cy]");
             for (std::size_t i = 0; i < 4; ++i) calib.intrinsics[i] = intrinsics[i];
             calib.distortion = distortion;
             calib.distortion_coeffs = coeffs;
             const auto camera = CameraModel::create(calib);
             sim::RenderOptions o;
             o.supersample = supersample;
             o.read_noise = read_noise;
             o.shot_noise = shot_noise;
             o.vignetting = vignetting;
             o.background = background;
             o.near_m = near_m;
             o.lod_bias = lod_bias;
             py::gil_scoped_release release;
             return std::make_unique<sim::Renderer>(*camera, o);
           }),
           py::arg("width"), py::arg("height"), py::arg("intrinsics"), py::arg("distortion") = "radtan",
           py::arg("distortion_coeffs") = std::vector<double>{}, py::arg("supersample") = 2,
           py::arg("read_noise") = 1.2, py::arg("shot_noise") = 0.04, py::arg("vignetting") = 0.25,
           py::arg("background") = 0.0, py::arg("near_m") = 0.05, py::arg("lod_bias") = 0.0)
      .def_property_readonly("width", &sim::Renderer::width)
      .def_property_readonly("height", &sim::Renderer::height)
      .def(
          "render_radiance",
          [](const sim::Renderer& r, const sim::Scene& scene, const F64Array& T_W_C) {
            const Pose T = toPose(T_W_C);
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = r.renderRadiance(scene, T);
            }
            return toNumpy<float>(out);
          },
          py::arg("scene"), py::arg("T_W_C"), "Noise-free float32 radiance (grey levels) from camera pose T_W_C.")
      .def(
          "render_radiance_blurred",
          [](const sim::Renderer& r, const sim::Scene& scene, const std::vector<F64Array>& poses) {
            std::vector<Pose> T;
            for (const auto& p : poses) T.push_back(toPose(p));
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = r.renderRadianceBlurred(scene, T);
            }
            return toNumpy<float>(out);
          },
          py::arg("scene"), py::arg("poses"), "Mean radiance over several poses (motion blur).")
      .def(
          "expose",
          [](const sim::Renderer& r, const py::array_t<float, py::array::c_style | py::array::forcecast>& radiance,
             double gain, std::uint64_t seed) {
            if (radiance.ndim() != 2) throw InputError("sim.Renderer.expose: radiance must be 2-D");
            cv::Mat rad(static_cast<int>(radiance.shape(0)), static_cast<int>(radiance.shape(1)), CV_32FC1);
            std::memcpy(rad.data, radiance.data(), sizeof(float) * static_cast<std::size_t>(radiance.size()));
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = r.expose(rad, gain, seed);
            }
            return toNumpy<std::uint8_t>(out);
          },
          py::arg("radiance"), py::arg("gain") = 1.0, py::arg("seed") = 0,
          "Radiance -> uint8 image with gain, vignetting and seeded sensor noise.")
      .def(
          "render",
          [](const sim::Renderer& r, const sim::Scene& scene, const F64Array& T_W_C, double gain,
             std::uint64_t seed) {
            const Pose T = toPose(T_W_C);
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = r.render(scene, T, gain, seed);
            }
            return toNumpy<std::uint8_t>(out);
          },
          py::arg("scene"), py::arg("T_W_C"), py::arg("gain") = 1.0, py::arg("seed") = 0)
      .def(
          "render_depth",
          [](const sim::Renderer& r, const sim::Scene& scene, const F64Array& T_W_C) {
            const Pose T = toPose(T_W_C);
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = r.renderDepth(scene, T);
            }
            return toNumpy<float>(out);
          },
          py::arg("scene"), py::arg("T_W_C"), "Depth z (m) at every pixel centre, 0 where nothing is hit.")
      .def(
          "render_quad_ids",
          [](const sim::Renderer& r, const sim::Scene& scene, const F64Array& T_W_C) {
            const Pose T = toPose(T_W_C);
            cv::Mat out;
            {
              py::gil_scoped_release release;
              out = r.renderQuadIds(scene, T);
            }
            return toNumpy<int>(out);
          },
          py::arg("scene"), py::arg("T_W_C"), "Index of the visible quad at every pixel centre, -1 for none.");
}

}  // namespace linnet::python
