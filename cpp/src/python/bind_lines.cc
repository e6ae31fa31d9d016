// Bindings of the line front-end: a LineTracker over numpy uint8 images with the calibration as plain values,
// per-frame numpy arrays out; detect_lines() for one image. Tracking and detection release the GIL.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "linnet/camera/camera_model.h"
#include "linnet/core/error.h"
#include "linnet/features/line_tracker.h"

namespace py = pybind11;

namespace linnet::python {
namespace {

using U8Array = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;
using F64Array = py::array_t<double, py::array::c_style | py::array::forcecast>;

cv::Mat grayView(const U8Array& a, const char* name) {
  if (a.ndim() != 2) throw UsageError(std::string(name) + " image must be a 2-D uint8 array (H x W, grey)");
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1,
                 const_cast<std::uint8_t*>(a.data()));
}

// Sets option fields from a {"a.b.c": value} dict by walking the options' visit(); unknown keys are errors.
class DictSetter {
 public:
  DictSetter(const py::dict& values, std::string prefix, std::vector<std::string>* used)
      : values_(values), prefix_(std::move(prefix)), used_(used) {}

  template <class T>
  void operator()(const char* key, T& value, const char* /*doc*/) {
    set(key, value);
  }
  template <class T>
  void operator()(const char* key, T& value, const char* /*doc*/, T /*lo*/, T /*hi*/) {
    set(key, value);
  }
  void choice(const char* key, std::string& value, const char* /*doc*/, std::initializer_list<const char*>) {
    set(key, value);
  }
  template <class S>
  void section(const char* key, S& sub) {
    DictSetter child(values_, path(key), used_);
    sub.visit(child);
  }

 private:
  template <class T>
  void set(const char* key, T& value) {
    const std::string p = path(key);
    if (!values_.contains(py::str(p))) return;
    try {
      value = values_[py::str(p)].template cast<T>();
    } catch (const py::cast_error&) {
      throw ConfigError("config key 'lines." + p + "' has the wrong type");
    }
    used_->push_back(p);
  }
  std::string path(const char* key) const { return prefix_.empty() ? std::string(key) : prefix_ + "." + key; }
  const py::dict& values_;
  std::string prefix_;
  std::vector<std::string>* used_;
};

// Dumps every option as {"a.b.c": value}.
class DictGetter {
 public:
  DictGetter(py::dict* out, std::string prefix) : out_(out), prefix_(std::move(prefix)) {}
  template <class T>
  void operator()(const char* key, T& value, const char* /*doc*/) {
    (*out_)[py::str(path(key))] = value;
  }
  template <class T>
  void operator()(const char* key, T& value, const char* /*doc*/, T /*lo*/, T /*hi*/) {
    (*out_)[py::str(path(key))] = value;
  }
  void choice(const char* key, std::string& value, const char* /*doc*/, std::initializer_list<const char*>) {
    (*out_)[py::str(path(key))] = value;
  }
  template <class S>
  void section(const char* key, S& sub) {
    DictGetter child(out_, path(key));
    sub.visit(child);
  }

 private:
  std::string path(const char* key) const { return prefix_.empty() ? std::string(key) : prefix_ + "." + key; }
  py::dict* out_;
  std::string prefix_;
};

template <class Options>
Options optionsFromDict(const py::dict& d) {
  Options o;
  std::vector<std::string> used;
  DictSetter setter(d, "", &used);
  o.visit(setter);
  for (const auto& item : d) {
    const std::string k = py::str(item.first);
    if (std::find(used.begin(), used.end(), k) == used.end())
      throw ConfigError("unknown config key 'lines." + k + "'");
  }
  return o;
}

std::unique_ptr<CameraModel> cameraFromDict(const py::dict& d, const char* which) {
  CameraCalibration c;
  auto need = [&](const char* k) {
    if (!d.contains(k)) throw ConfigError(std::string(which) + ": missing key '" + k + "'");
    return d[k];
  };
  c.width = need("width").cast<int>();
  c.height = need("height").cast<int>();
  const auto intr = need("intrinsics").cast<std::vector<double>>();
  if (intr.size() != 4) throw ConfigError(std::string(which) + ".intrinsics: expected fx, fy, cx, cy");
  for (int k = 0; k < 4; ++k) c.intrinsics[k] = intr[k];
  c.distortion = d.contains("distortion") ? d["distortion"].cast<std::string>() : std::string("none");
  c.distortion_coeffs =
      d.contains("distortion_coeffs") ? d["distortion_coeffs"].cast<std::vector<double>>() : std::vector<double>{};
  return CameraModel::create(c);
}

py::array_t<double> points2(const std::vector<Vec2>& v) {
  py::array_t<double> a({static_cast<py::ssize_t>(v.size()), py::ssize_t(2)});
  for (std::size_t i = 0; i < v.size(); ++i) {
    a.mutable_at(i, 0) = v[i].x();
    a.mutable_at(i, 1) = v[i].y();
  }
  return a;
}

py::dict observationsToDict(const std::vector<LineObservation>& obs) {
  const auto n = static_cast<py::ssize_t>(obs.size());
  py::array_t<std::int64_t> id(n);
  py::array_t<bool> has_right(n);
  py::array_t<int> length(n);
  std::vector<Vec2> s0, e0, ps0, pe0, s1, e1, ps1, pe1;
  for (py::ssize_t i = 0; i < n; ++i) {
    const LineObservation& o = obs[i];
    id.mutable_at(i) = o.id;
    has_right.mutable_at(i) = o.has_right;
    length.mutable_at(i) = o.track_length;
    s0.push_back(o.s0), e0.push_back(o.e0), ps0.push_back(o.ps0), pe0.push_back(o.pe0);
    s1.push_back(o.s1), e1.push_back(o.e1), ps1.push_back(o.ps1), pe1.push_back(o.pe1);
  }
  py::dict d;
  d["id"] = id;
  d["s0"] = points2(s0), d["e0"] = points2(e0), d["ps0"] = points2(ps0), d["pe0"] = points2(pe0);
  d["has_right"] = has_right;
  d["s1"] = points2(s1), d["e1"] = points2(e1), d["ps1"] = points2(ps1), d["pe1"] = points2(pe1);
  d["track_length"] = length;
  return d;
}

py::dict timingsToDict(const LineFrameTimings& t) {
  py::dict d;
  d["detect_ms"] = t.detect_ms, d["merge_ms"] = t.merge_ms, d["describe_ms"] = t.describe_ms;
  d["temporal_ms"] = t.temporal_ms, d["stereo_ms"] = t.stereo_ms, d["left_ms"] = t.left_ms;
  d["total_ms"] = t.total_ms;
  d["cpu_left_ms"] = t.cpu_left_ms, d["cpu_total_ms"] = t.cpu_total_ms;
  d["detected_left"] = t.detected_left, d["detected_right"] = t.detected_right, d["tracked"] = t.tracked;
  d["new_lines"] = t.new_lines, d["stereo_matched"] = t.stereo_matched, d["stereo_guided"] = t.stereo_guided;
  d["right_detected"] = t.right_detected;
  d["left_detected"] = t.left_detected, d["left_predicted"] = t.left_predicted;
  return d;
}

// Owns the camera models the tracker refers to.
class PyLineTracker {
 public:
  PyLineTracker(const py::dict& cam0, const py::object& cam1, const py::object& T_C1_C0, const py::dict& options)
      : options_(optionsFromDict<LineTrackerOptions>(options)), cam0_(cameraFromDict(cam0, "cam0")) {
    Pose T;
    if (!cam1.is_none()) {
      cam1_ = cameraFromDict(cam1.cast<py::dict>(), "cam1");
      if (T_C1_C0.is_none()) throw ConfigError("T_C1_C0 (4x4) is required with cam1");
      const F64Array M = T_C1_C0.cast<F64Array>();
      if (M.ndim() != 2 || M.shape(0) != 4 || M.shape(1) != 4) throw ConfigError("T_C1_C0 must be a 4x4 array");
      Mat4 m;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c < 4; ++c) m(r, c) = M.at(r, c);
      T = Pose::fromMatrix(m);
    }
    tracker_ = std::make_unique<LineTracker>(options_, *cam0_, cam1_.get(), T);
  }

  py::dict track(std::int64_t t_ns, const U8Array& left, const py::object& right) {
    const cv::Mat l = grayView(left, "left");
    U8Array right_arr;
    cv::Mat r;
    if (!right.is_none()) {
      right_arr = right.cast<U8Array>();
      r = grayView(right_arr, "right");
    }
    std::vector<LineObservation> obs;
    {
      py::gil_scoped_release release;
      tracker_->track(t_ns, l, r, &obs);
    }
    return observationsToDict(obs);
  }

  void setRotationPrediction(const py::object& R) {
    const F64Array M = R.cast<F64Array>();
    if (M.ndim() != 2 || M.shape(0) != 3 || M.shape(1) != 3) throw UsageError("R_cur_prev must be a 3x3 array");
    Mat3 m;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) m(r, c) = M.at(r, c);
    tracker_->setRotationPrediction(m);
  }

  py::dict lastTimings() const { return timingsToDict(tracker_->lastTimings()); }

  py::dict options() {
    py::dict d;
    DictGetter g(&d, "");
    options_.visit(g);
    return d;
  }

 private:
  LineTrackerOptions options_;
  std::unique_ptr<CameraModel> cam0_, cam1_;
  std::unique_ptr<LineTracker> tracker_;
};

}  // namespace

void bindLines(py::module_& m) {
  py::class_<PyLineTracker>(m, "LineTracker", R"doc(
Line front-end (detection, merging, LBD, temporal and stereo matching) over numpy images.

cam0 / cam1: dicts {width, height, intrinsics: [fx, fy, cx, cy], distortion: "radtan" | "equidistant" | "none",
distortion_coeffs: [...]}; cam1 = None for mono. T_C1_C0: 4x4 array mapping cam0 coordinates to cam1.
options: {"key.path": value} overrides of LineTrackerOptions, e.g. {"detection.detector": "lsd", "max_lines": 100}.
)doc")
      .def(py::init<const py::dict&, const py::object&, const py::object&, const py::dict&>(), py::arg("cam0"),
           py::arg("cam1") = py::none(), py::arg("T_C1_C0") = py::none(), py::arg("options") = py::dict())
      .def("track", &PyLineTracker::track, py::arg("t_ns"), py::arg("left"), py::arg("right") = py::none(),
           "Tracks one frame. Returns a dict of arrays (N lines, sorted by id): id, s0, e0 (normalised cam0), ps0, "
           "pe0 (pixels cam0), has_right, s1, e1, ps1, pe1 (cam1, valid where has_right), track_length.")
      .def("set_rotation_prediction", &PyLineTracker::setRotationPrediction, py::arg("R_cur_prev"),
           "Rotation of cam0 from the previous to the next frame (3x3, p_cur = R p_prev), used by the next track().")
      .def("last_timings", &PyLineTracker::lastTimings,
           "Stage wall times of the last frame (ms): detect, merge, describe, temporal, stereo, left, total; thread CPU "
           "times cpu_left, cpu_total; and counts.")
      .def("options", &PyLineTracker::options, "All options as a flat {key.path: value} dict.");

  m.def(
      "detect_lines",
      [](const U8Array& image, const py::dict& options) {
        const LineTrackerOptions o = optionsFromDict<LineTrackerOptions>(options);
        const cv::Mat img = grayView(image, "image");
        std::vector<LineSegment> segs;
        {
          py::gil_scoped_release release;
          LineDetector det(o.detection);
          det.detect(img, &segs);
        }
        py::array_t<double> out({static_cast<py::ssize_t>(segs.size()), py::ssize_t(4)});
        for (std::size_t i = 0; i < segs.size(); ++i) {
          out.mutable_at(i, 0) = segs[i].s.x();
          out.mutable_at(i, 1) = segs[i].s.y();
          out.mutable_at(i, 2) = segs[i].e.x();
          out.mutable_at(i, 3) = segs[i].e.y();
        }
        return out;
      },
      py::arg("image"), py::arg("options") = py::dict(),
      "Detects (refined, oriented) segments in one grey image: (N, 4) array x0, y0, x1, y1 in pixels, longest first. "
      "options: LineTrackerOptions overrides (the detection.* keys matter).");
}

}  // namespace linnet::python
