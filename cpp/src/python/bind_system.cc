// Bindings of the public API: Config, System, FrameResult, dataset runs. Plain value types in, numpy arrays out.
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "linnet/core/error.h"
#include "linnet/pipeline/config.h"
#include "linnet/pipeline/dataset_runner.h"
#include "linnet/pipeline/system.h"

namespace py = pybind11;

namespace linnet::python {

namespace {

const char* statusName(TrackingStatus s) {
  switch (s) {
    case TrackingStatus::kInitialising:
      return "initialising";
    case TrackingStatus::kTracking:
      return "tracking";
    case TrackingStatus::kLost:
      return "lost";
  }
  return "unknown";
}

Vec3 toVec3(const py::array_t<double, py::array::c_style | py::array::forcecast>& a, const char* name) {
  if (a.size() != 3) throw UsageError(std::string(name) + " must have 3 elements");
  return Vec3(a.at(0), a.at(1), a.at(2));
}

// A cv::Mat header over a numpy uint8 image (H x W, or H x W x 3). The System copies what it keeps.
cv::Mat toMat(const py::array& image, const char* name) {
  if (!py::isinstance<py::array_t<std::uint8_t>>(image))
    throw UsageError(std::string(name) + " image must be a numpy uint8 array");
  py::array_t<std::uint8_t, py::array::c_style> a = py::array_t<std::uint8_t, py::array::c_style>::ensure(image);
  if (a.ndim() == 2) return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1, a.mutable_data());
  if (a.ndim() == 3 && (a.shape(2) == 3 || a.shape(2) == 4))
    return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC(static_cast<int>(a.shape(2))),
                   a.mutable_data());
  throw UsageError(std::string(name) + " image must be H x W (gray) or H x W x 3 (BGR)");
}

py::dict resultsToArrays(const std::vector<FrameResult>& results, bool only_with_pose) {
  std::vector<const FrameResult*> sel;
  for (const FrameResult& r : results)
    if (!only_with_pose || r.estimate.has_pose) sel.push_back(&r);
  const py::ssize_t n = static_cast<py::ssize_t>(sel.size());
  py::array_t<std::int64_t> t(n);
  py::array_t<double> p({n, py::ssize_t(3)}), q({n, py::ssize_t(4)}), v({n, py::ssize_t(3)}),
      ba({n, py::ssize_t(3)}), bg({n, py::ssize_t(3)});
  py::array_t<bool> has_pose(n), keyframe(n);
  py::array_t<double> frontend_ms(n), backend_ms(n);
  py::array_t<int> points(n), lines(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    const EstimatorOutput& e = sel[i]->estimate;
    t.mutable_at(i) = e.t;
    for (int k = 0; k < 3; ++k) {
      p.mutable_at(i, k) = e.T_W_B.p[k];
      v.mutable_at(i, k) = e.v_W[k];
      ba.mutable_at(i, k) = e.b_a[k];
      bg.mutable_at(i, k) = e.b_g[k];
    }
    q.mutable_at(i, 0) = e.T_W_B.q.x();
    q.mutable_at(i, 1) = e.T_W_B.q.y();
    q.mutable_at(i, 2) = e.T_W_B.q.z();
    q.mutable_at(i, 3) = e.T_W_B.q.w();
    has_pose.mutable_at(i) = e.has_pose;
    keyframe.mutable_at(i) = e.keyframe;
    frontend_ms.mutable_at(i) = sel[i]->frontend_ms;
    backend_ms.mutable_at(i) = sel[i]->backend_ms;
    points.mutable_at(i) = sel[i]->tracked_points;
    lines.mutable_at(i) = sel[i]->tracked_lines;
  }
  py::dict d;
  d["t_ns"] = t;
  d["position"] = p;
  d["quaternion_xyzw"] = q;
  d["velocity"] = v;
  d["bias_acc"] = ba;
  d["bias_gyr"] = bg;
  d["has_pose"] = has_pose;
  d["keyframe"] = keyframe;
  d["frontend_ms"] = frontend_ms;
  d["backend_ms"] = backend_ms;
  d["points"] = points;
  d["lines"] = lines;
  return d;
}

py::array_t<double> pointsToArray(const std::vector<Vec3>& pts) {
  py::array_t<double> a({static_cast<py::ssize_t>(pts.size()), py::ssize_t(3)});
  for (std::size_t i = 0; i < pts.size(); ++i)
    for (int k = 0; k < 3; ++k) a.mutable_at(static_cast<py::ssize_t>(i), k) = pts[i][k];
  return a;
}

py::dict mapToDict(const std::vector<Vec3>& points, const std::vector<MapLine>& lines) {
  const py::ssize_t n = static_cast<py::ssize_t>(lines.size());
  py::array_t<double> segs({n, py::ssize_t(2), py::ssize_t(3)});
  py::array_t<std::int64_t> ids(n);
  py::array_t<int> obs(n);
  for (py::ssize_t i = 0; i < n; ++i) {
    const MapLine& l = lines[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      segs.mutable_at(i, 0, k) = l.a[k];
      segs.mutable_at(i, 1, k) = l.b[k];
    }
    ids.mutable_at(i) = l.id;
    obs.mutable_at(i) = l.observations;
  }
  py::dict d;
  d["points"] = pointsToArray(points);
  d["lines"] = segs;
  d["line_ids"] = ids;
  d["line_observations"] = obs;
  return d;
}

}  // namespace

void bindSystem(py::module_& m) {
  py::register_exception<Error>(m, "Error", PyExc_RuntimeError);
  py::register_exception<InputError>(m, "InputError", m.attr("Error").ptr());
  py::register_exception<ConfigError>(m, "ConfigError", m.attr("Error").ptr());
  py::register_exception<UsageError>(m, "UsageError", m.attr("Error").ptr());

  py::class_<Config>(m, "Config", "Root configuration (one options section per module); YAML in and out.")
      .def(py::init([] { return Config::eurocStereoImu(); }))
      .def_static("euroc_stereo_imu", &Config::eurocStereoImu, "EuRoC stereo-inertial defaults")
      .def_static("load", &Config::load, py::arg("path"), "Defaults overridden by a YAML file")
      .def_static("from_yaml", &Config::fromYaml, py::arg("text"), py::arg("source") = "<yaml>")
      .def_static("for_euroc", [](const std::string& dataset, const Config* base) {
            return configForEuroc(dataset, base ? *base : Config::eurocStereoImu());
          }, py::arg("dataset"), py::arg("base") = nullptr,
          "Config with the calibration (cameras, IMU noise) of a EuRoC folder")
      .def("merge", &Config::merge, py::arg("path"))
      .def("merge_yaml", &Config::mergeYaml, py::arg("text"), py::arg("source") = "<yaml>")
      .def("save", &Config::save, py::arg("path"))
      .def("to_yaml", &Config::toYaml)
      .def("validate", &Config::validate)
      .def_property("stereo", [](const Config& c) { return c.stereo; }, [](Config& c, bool s) { c.stereo = s; })
      .def_property("blocking", [](const Config& c) { return c.pipeline.blocking; },
                    [](Config& c, bool b) { c.pipeline.blocking = b; })
      .def_property("use_lines", [](const Config& c) { return c.pipeline.use_lines; },
                    [](Config& c, bool b) { c.pipeline.use_lines = b; })
      .def("__repr__", [](const Config& c) { return "<linnet.Config stereo=" + std::string(c.stereo ? "True" : "False") + ">"; });

  py::class_<FrameResult>(m, "FrameResult", "What the System reports for one processed frame")
      .def_property_readonly("t_ns", [](const FrameResult& r) { return r.estimate.t; })
      .def_property_readonly("status", [](const FrameResult& r) { return statusName(r.estimate.status); })
      .def_property_readonly("has_pose", [](const FrameResult& r) { return r.estimate.has_pose; })
      .def_property_readonly("position", [](const FrameResult& r) { return Vec3(r.estimate.T_W_B.p); })
      .def_property_readonly("quaternion_xyzw", [](const FrameResult& r) {
        return Vec4(r.estimate.T_W_B.q.x(), r.estimate.T_W_B.q.y(), r.estimate.T_W_B.q.z(), r.estimate.T_W_B.q.w());
      })
      .def_property_readonly("velocity", [](const FrameResult& r) { return r.estimate.v_W; })
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
      .def_property_readonly("landmark_points", [](const FrameResult& r) { return r.estimate.num_points; })
      .def_property_readonly("landmark_lines", [](const FrameResult& r) { return r.estimate.num_lines; });

  py::class_<System>(m, "System", "Stereo/mono + IMU SLAM system: add_imu / add_stereo / add_mono, then finish()")
      .def(py::init<const Config&>(), py::arg("config"))
      .def("add_imu", [](System& s, std::int64_t t_ns, py::array_t<double, py::array::c_style | py::array::forcecast> acc,
                         py::array_t<double, py::array::c_style | py::array::forcecast> gyr) {
             s.addImu(t_ns, toVec3(acc, "acc"), toVec3(gyr, "gyr"));
           }, py::arg("t_ns"), py::arg("acc"), py::arg("gyr"))
      .def("add_stereo", [](System& s, std::int64_t t_ns, const py::array& left, const py::array& right) {
             cv::Mat l = toMat(left, "left"), r = toMat(right, "right");
             py::gil_scoped_release release;
             return s.addStereo(t_ns, l, r);
           }, py::arg("t_ns"), py::arg("left"), py::arg("right"))
      .def("add_mono", [](System& s, std::int64_t t_ns, const py::array& image) {
             cv::Mat im = toMat(image, "image");
             py::gil_scoped_release release;
             return s.addMono(t_ns, im);
           }, py::arg("t_ns"), py::arg("image"))
      .def("set_callback", [](System& s, py::function cb) {
             auto holder = std::make_shared<py::function>(std::move(cb));
             s.setCallback([holder](const FrameResult& r) {
               py::gil_scoped_acquire gil;
               (*holder)(r);
             });
           }, py::arg("callback"), "callback(FrameResult), called on the estimator thread in time order")
      .def("finish", [](System& s) {
             py::gil_scoped_release release;
             s.finish();
           })
      .def("trajectory", [](const System& s, bool only_with_pose) { return resultsToArrays(s.trajectory(), only_with_pose); },
           py::arg("only_with_pose") = true, "dict of numpy arrays: t_ns, position, quaternion_xyzw, velocity, ...")
      .def("results", &System::trajectory, "list of FrameResult")
      .def("map", [](const System& s) {
             const SystemMap map = s.map();
             return mapToDict(map.points, map.lines);
           }, "dict: points (N x 3), lines (M x 2 x 3 segment endpoints), line_ids (M), line_observations (M); W, "
              "metres; empty until finish()")
      .def_property_readonly("dropped_frames", &System::droppedFrames);

  py::class_<RunSummary>(m, "RunSummary", "Result of a dataset run")
      .def_readonly("frames", &RunSummary::frames)
      .def_readonly("processed_frames", &RunSummary::processed_frames)
      .def_readonly("frames_with_pose", &RunSummary::frames_with_pose)
      .def_readonly("dropped_frames", &RunSummary::dropped_frames)
      .def_readonly("init_time_s", &RunSummary::init_time_s)
      .def_readonly("reinitialisations", &RunSummary::reinitialisations)
      .def_readonly("wall_time_s", &RunSummary::wall_time_s)
      .def_readonly("sequence_duration_s", &RunSummary::sequence_duration_s)
      .def_readonly("real_time_factor", &RunSummary::real_time_factor)
      .def_readonly("cpu_time_s", &RunSummary::cpu_time_s)
      .def_readonly("cpu_real_time_factor", &RunSummary::cpu_real_time_factor)
      .def_readonly("image_load_cpu_s", &RunSummary::image_load_cpu_s)
      .def("trajectory", [](const RunSummary& r, bool only_with_pose) { return resultsToArrays(r.results, only_with_pose); },
           py::arg("only_with_pose") = true)
      .def("map", [](const RunSummary& r) { return mapToDict(r.map_points, r.map_lines); },
           "dict: points (N x 3), lines (M x 2 x 3), line_ids (M), line_observations (M); W, metres")
      .def("results", [](const RunSummary& r) { return r.results; }, "list of FrameResult, one per processed frame")
      .def("write", [](const RunSummary& r, const std::string& out_dir) { writeRunOutputs(r, out_dir); },
           py::arg("out_dir"), "trajectory.tum, trajectory.csv, timing.csv, map.ply, map_lines.csv into out_dir");

  m.def("run_euroc", [](const std::string& dataset, const Config& config, int max_frames, double start_s,
                        std::optional<py::function> progress) {
          RunOptions opt;
          opt.max_frames = max_frames;
          opt.start_s = start_s;
          if (progress) {
            auto holder = std::make_shared<py::function>(*progress);
            opt.progress = [holder](int done, int total) {
              py::gil_scoped_acquire gil;
              (*holder)(done, total);
            };
          }
          py::gil_scoped_release release;
          return runEuroc(dataset, config, opt);
        }, py::arg("dataset"), py::arg("config"), py::arg("max_frames") = -1, py::arg("start_s") = 0.0,
        py::arg("progress") = py::none(), "Runs a EuRoC folder (blocking, deterministic) and returns a RunSummary");
}

}  // namespace linnet::python
