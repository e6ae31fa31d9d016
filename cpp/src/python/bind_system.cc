// Bindings of the System (frame by frame) and its FrameResult.
//
// Python callbacks run on the estimator thread. An exception raised by one must not cross that thread (it would
// abort the process); it is kept, the callback is not called again, and the exception is raised once, on the
// caller's thread, by the next add_* / finish call. The System keeps running.
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <memory>
#include <mutex>
#include <string>

#include "bind_arrays.h"
#include "bind_callbacks.h"
#include "bind_images.h"
#include "linnet/core/error.h"
#include "linnet/pipeline/system.h"

namespace py = pybind11;

namespace linnet::python {

namespace {

/// The first exception a Python callback raised, until it is handed to the caller.
struct CallbackFailure {
  std::mutex mutex;
  py::object exception;  // the exception instance (None: none pending); touched with the GIL held
  bool failed = false;   // once true, the callback is not called again
};

/// System plus the state of its Python callback.
class PySystem {
 public:
  explicit PySystem(const Config& config) : system_(config), failure_(std::make_shared<CallbackFailure>()) {}
  /// Deleted without finish() (an exception in the caller's loop, interpreter exit): the estimator thread may be
  /// waiting for the GIL in a callback, so the threads are stopped with the GIL released and the callback removed.
  ~PySystem() {
    py::gil_scoped_release release;
    try {
      system_.setCallback(nullptr);
      system_.finish();
    } catch (...) {  // a worker error nobody will read: the object is going away
    }
  }
  PySystem(const PySystem&) = delete;
  PySystem& operator=(const PySystem&) = delete;

  void setCallback(py::function cb) {
    // The estimator thread copies the callback; whichever copy goes last deletes the function, with the GIL.
    auto holder = holdFunction(std::move(cb));
    std::weak_ptr<CallbackFailure> weak = failure_;
    system_.setCallback([holder, weak](const FrameResult& r) {
      py::gil_scoped_acquire gil;
      const auto failure = weak.lock();
      if (!failure || failure->failed) return;
      try {
        (*holder)(r);
      } catch (py::error_already_set& e) {
        std::lock_guard<std::mutex> lock(failure->mutex);
        failure->failed = true;
        failure->exception = e.value();
      }
    });
  }

  /// Raises (once) the exception a callback raised, with the GIL held.
  void raisePending() {
    py::object exc;
    {
      std::lock_guard<std::mutex> lock(failure_->mutex);
      if (!failure_->exception || failure_->exception.is_none()) return;
      exc = std::move(failure_->exception);
      failure_->exception = py::none();
    }
    PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(exc.ptr())), exc.ptr());
    throw py::error_already_set();
  }

  System& system() { return system_; }

 private:
  System system_;
  std::shared_ptr<CallbackFailure> failure_;
};

/// add_imu's time stamps: an int, or a 1-D array (or N x 1) of them.
py::array_t<std::int64_t, py::array::c_style> timesOf(const py::object& t_ns) {
  auto t = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>::ensure(t_ns);
  if (!t) throw UsageError("t_ns must be an integer (ns) or an array of them");
  return t;
}

/// acc / gyr of N samples: a 3-vector when N == 1, or an N x 3 array.
py::array_t<double, py::array::c_style> vectorsOf(const py::object& a, py::ssize_t n, const char* name) {
  auto v = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  if (!v || v.size() != 3 * n || (n > 1 && (v.ndim() != 2 || v.shape(1) != 3)))
    throw UsageError(std::string(name) + " must be " + (n == 1 ? "3 numbers" : "an N x 3 array with N = " +
                                                                                   std::to_string(n)) +
                     " (one row per time stamp)");
  return v;
}

void addImu(PySystem& s, const py::object& t_ns, const py::object& acc, const py::object& gyr) {
  s.raisePending();
  const auto t = timesOf(t_ns);
  const py::ssize_t n = t.size();
  const auto a = vectorsOf(acc, n, "acc");
  const auto g = vectorsOf(gyr, n, "gyr");
  const double* ad = a.data();
  const double* gd = g.data();
  for (py::ssize_t i = 0; i < n; ++i)
    s.system().addImu(t.data()[i], Vec3(ad[3 * i], ad[3 * i + 1], ad[3 * i + 2]),
                      Vec3(gd[3 * i], gd[3 * i + 1], gd[3 * i + 2]));
}

}  // namespace

void bindSystem(py::module_& m) {
  py::register_exception<Error>(m, "Error", PyExc_RuntimeError);
  py::register_exception<InputError>(m, "InputError", m.attr("Error").ptr());
  py::register_exception<ConfigError>(m, "ConfigError", m.attr("Error").ptr());
  py::register_exception<UsageError>(m, "UsageError", m.attr("Error").ptr());

  py::class_<FrameResult>(m, "FrameResult", "What the System reports for one processed frame")
      .def_property_readonly("t_ns", [](const FrameResult& r) { return r.estimate.t; })
      .def_property_readonly("status", [](const FrameResult& r) { return toString(r.estimate.status); })
      .def_property_readonly("has_pose", [](const FrameResult& r) { return r.estimate.has_pose; })
      .def_property_readonly("position", [](const FrameResult& r) { return Vec3(r.T_W_B.p); })
      .def_property_readonly("quaternion_xyzw", [](const FrameResult& r) {
        return Vec4(r.T_W_B.q.x(), r.T_W_B.q.y(), r.T_W_B.q.z(), r.T_W_B.q.w());
      })
      .def_property_readonly("velocity", [](const FrameResult& r) { return r.v_W; })
      .def_property_readonly("bias_acc", [](const FrameResult& r) { return r.estimate.b_a; })
      .def_property_readonly("bias_gyr", [](const FrameResult& r) { return r.estimate.b_g; })
      .def_property_readonly("keyframe", [](const FrameResult& r) { return r.estimate.keyframe; })
      .def_property_readonly("reinitialisations", [](const FrameResult& r) { return r.estimate.reinitialisations; })
      .def_readonly("tracked_points", &FrameResult::tracked_points)
      .def_readonly("stereo_points", &FrameResult::stereo_points)
      .def_readonly("tracked_lines", &FrameResult::tracked_lines)
      .def_readonly("frontend_ms", &FrameResult::frontend_ms)
      .def_readonly("backend_ms", &FrameResult::backend_ms)
      .def_readonly("point_cpu_ms", &FrameResult::point_cpu_ms)
      .def_readonly("line_cpu_ms", &FrameResult::line_cpu_ms)
      .def_readonly("backend_cpu_ms", &FrameResult::backend_cpu_ms)
      .def_readonly("line_backend_ms", &FrameResult::line_backend_ms)
      .def_readonly("solver_ms", &FrameResult::solver_ms)
      .def_readonly("loop_cpu_ms", &FrameResult::loop_cpu_ms)
      .def_readonly("rss_mb", &FrameResult::rss_mb, "the process's resident set size after the frame, MB")
      .def_property_readonly("landmark_points", [](const FrameResult& r) { return r.estimate.num_points; })
      .def_property_readonly("landmark_lines", [](const FrameResult& r) { return r.estimate.num_lines; })
      .def_property_readonly(
          "reidentified_lines", [](const FrameResult& r) { return r.estimate.reidentified_lines; },
          "new line tracks found to continue a window line in this frame (estimator.lines.reidentify)")
      .def_property_readonly(
          "time_offset_s", [](const FrameResult& r) { return r.estimate.time_offset_s; },
          "camera-to-IMU time offset in use (camera stamp - capture time), s (estimator.time_offset)")
      .def_property_readonly(
          "extrinsics_correction", [](const FrameResult& r) { return Eigen::Matrix4d(r.estimate.T_B_R.matrix()); },
          "online correction T_B_R of the rig's extrinsics (4x4; cameras at T_B_R @ T_B_Ci; identity unless "
          "estimator.extrinsics.estimate)")
      .def_property_readonly(
          "stereo_correction", [](const FrameResult& r) { return Eigen::Matrix4d(r.estimate.S_C1.matrix()); },
          "online correction S of cam1 relative to cam0 (4x4; cam1 at T_B_R @ T_B_C1 @ S; identity unless "
          "estimator.extrinsics.estimate_stereo)");

  py::class_<PySystem>(m, "System",
                       "Stereo/mono + IMU SLAM system: add_imu / add_stereo / add_mono in time order, then finish()")
      .def(py::init<const Config&>(), py::arg("config"))
      .def("add_imu", &addImu, py::arg("t_ns"), py::arg("acc"), py::arg("gyr"),
           "IMU samples, body frame, SI: t_ns an int (ns) with acc / gyr 3-vectors (m/s^2, rad/s), or N time "
           "stamps with N x 3 arrays. Time stamps must increase strictly.")
      .def("add_stereo", [](PySystem& s, std::int64_t t_ns, const py::array& left, const py::array& right) {
             s.raisePending();
             const ImageView l(left, "left"), r(right, "right");
             py::gil_scoped_release release;
             return s.system().addStereo(t_ns, l.mat, r.mat);
           }, py::arg("t_ns"), py::arg("left"), py::arg("right"),
           "A stereo pair (uint8 H x W gray or H x W x 3 BGR, any memory layout) at t_ns. Returns True when the "
           "frame was queued, False when it was dropped (real-time mode only: the front-end was busy). Raises "
           "linnet.UsageError for a wrong size / type or a time stamp not after the previous frame's.")
      .def("add_mono", [](PySystem& s, std::int64_t t_ns, const py::array& image) {
             s.raisePending();
             const ImageView im(image, "image");
             py::gil_scoped_release release;
             return s.system().addMono(t_ns, im.mat);
           }, py::arg("t_ns"), py::arg("image"), "A monocular image (config.stereo False); returns as add_stereo")
      .def("set_callback", &PySystem::setCallback, py::arg("callback"),
           "callback(FrameResult), called on the estimator thread in time order. If it raises, it is not called "
           "again and the exception is raised by the next add_* / finish call.")
      .def("finish", [](PySystem& s) {
             {
               py::gil_scoped_release release;
               s.system().finish();
             }
             s.raisePending();
           }, "Processes everything queued and stops the threads (idempotent)")
      .def("trajectory", [](PySystem& s, bool only_with_pose) {
             return resultsToArrays(s.system().trajectory(), only_with_pose);
           }, py::arg("only_with_pose") = true, "dict of numpy arrays: t_ns, position, quaternion_xyzw, velocity, ...")
      .def("results", [](PySystem& s) { return s.system().trajectory(); }, "list of FrameResult")
      .def("map", [](PySystem& s) {
             const SystemMap map = s.system().map();
             return mapToDict(map.points, map.lines);
           }, "dict: points (N x 3), lines (M x 2 x 3 segment endpoints), line_ids (M), line_observations (M); W, "
              "metres; the published lines (estimator.lines.map.max_sigma_m); empty until finish()")
      .def_property_readonly("dropped_frames", [](PySystem& s) { return s.system().droppedFrames(); });
}

}  // namespace linnet::python
