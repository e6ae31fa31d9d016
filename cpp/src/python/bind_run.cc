// Bindings of whole runs: a EuRoC folder (run_euroc), any other source fed sample by sample (StreamRun), and the
// RunSummary both return.
#include <pybind11/functional.h>
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>

#include "bind_arrays.h"
#include "bind_callbacks.h"
#include "bind_images.h"
#include "linnet/pipeline/dataset_runner.h"

namespace py = pybind11;

namespace linnet::python {

void bindRun(py::module_& m) {
  py::class_<RunSummary>(m, "RunSummary", "Result of a run (a dataset, or a StreamRun)")
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
      .def_readonly("first_frame_t_ns", &RunSummary::first_frame_t)
      .def_readonly("last_frame_t_ns", &RunSummary::last_frame_t)
      .def_readonly("first_imu_t_ns", &RunSummary::first_imu_t)
      .def_readonly("last_imu_t_ns", &RunSummary::last_imu_t)
      .def_readonly("imu_samples", &RunSummary::imu_samples)
      .def_property_readonly(
          "map_line_count", [](const RunSummary& r) { return r.map_lines.size(); },
          "lines in the run's published line map")
      .def_property_readonly(
          "map_line_candidates", [](const RunSummary& r) { return r.line_curation.input; },
          "lines the estimator's map held before curation (estimator.lines.map)")
      .def_property_readonly(
          "line_adjustment",
          [](const RunSummary& r) -> py::object {
            const LineAdjustmentStats& a = r.line_adjustment;
            if (a.lines == 0) return py::none();
            py::dict d;
            d["lines"] = a.lines;
            d["joined"] = a.joined;
            d["groups"] = a.groups;
            d["solved"] = a.solved;
            d["cpu_s"] = a.cpu_s;
            return d;
          },
          "the line map's global adjustment (estimator.lines.map.adjust): lines, joined, groups, solved, cpu_s; "
          "None when it did not run")
      .def_readonly("reidentified_lines", &RunSummary::reidentified_lines,
                    "new line tracks found to continue a window line (estimator.lines.reidentify)")
      .def_readonly("stereo", &RunSummary::stereo)
      .def_readonly("warnings", &RunSummary::warnings)
      .def_readonly("extrinsics_estimated", &RunSummary::extrinsics_estimated)
      .def_property_readonly(
          "extrinsics_correction", [](const RunSummary& r) { return Eigen::Matrix4d(r.extrinsics_correction.matrix()); },
          "online correction T_B_R of the rig's extrinsics (4x4; cameras at T_B_R @ T_B_Ci)")
      .def_readonly("stereo_correction_estimated", &RunSummary::stereo_correction_estimated)
      .def_property_readonly(
          "stereo_correction", [](const RunSummary& r) { return Eigen::Matrix4d(r.stereo_correction.matrix()); },
          "online correction S of cam1 relative to cam0 (4x4; cam1 at T_B_R @ T_B_C1 @ S)")
      .def_readonly("time_offset_estimated", &RunSummary::time_offset_estimated)
      .def_readonly("time_offset_s", &RunSummary::time_offset_s)
      .def_readonly("loop_enabled", &RunSummary::loop_enabled)
      .def_property_readonly(
          "loop_stats",
          [](const RunSummary& r) {
            py::dict d;
            d["keyframes"] = r.loop_stats.keyframes;
            d["graph_nodes"] = r.loop_stats.graph_nodes;
            d["described"] = r.loop_stats.described;
            d["graph_solves"] = r.loop_stats.graph_solves;
            d["place_mb"] = r.loop_stats.place_mb;
            return d;
          },
          "the loop closer's counts: keyframes inserted, of which kept as pose-graph nodes and with a place "
          "description, its pose-graph solves, and the place descriptions' memory (place_mb)")
      .def_property_readonly(
          "loops",
          [](const RunSummary& r) {
            py::list out;
            for (const LoopEvent& e : r.loops) {
              py::dict d;
              d["t_new_ns"] = e.t_new;
              d["t_old_ns"] = e.t_old;
              d["inliers"] = e.inliers;
              d["correction_m"] = e.correction_m;
              d["correction_yaw_deg"] = e.correction_yaw_deg;
              d["T_old_new"] = Eigen::Matrix4d(e.T_old_new.matrix());
              d["sigma_m"] = e.sigma_m;
              d["sigma_yaw_deg"] = e.sigma_yaw_deg;
              d["method"] = placeMatchMethodName(e.method);
              out.append(d);
            }
            return out;
          },
          "loops closed: list of dicts (t_new_ns, t_old_ns, inliers, correction_m, correction_yaw_deg, T_old_new: the "
          "measured pose of the new keyframe's body in the old one's, 4 x 4, sigma_m, sigma_yaw_deg: its pose-graph "
          "edge's sigmas, method: descriptors, guided or lines, how it was verified)")
      .def("trajectory", [](const RunSummary& r, bool only_with_pose) { return resultsToArrays(r.results, only_with_pose); },
           py::arg("only_with_pose") = true)
      .def("map", [](const RunSummary& r) { return mapToDict(r.map_points, r.map_lines); },
           "dict: points (N x 3), lines (M x 2 x 3), line_ids (M), line_observations (M), line_sigma_m (M, predicted "
           "endpoint standard deviation, inf if unknown); W, metres")
      .def("results", [](const RunSummary& r) { return r.results; }, "list of FrameResult, one per processed frame")
      .def("write", [](const RunSummary& r, const std::string& out_dir) { writeRunOutputs(r, out_dir); },
           py::arg("out_dir"),
           "trajectory.tum, trajectory.csv, timing.csv, map.ply, map_lines.csv (and odometry.tum and loops.csv with "
           "loop closure) into out_dir");

  py::class_<StreamRun>(m, "StreamRun",
                        "A run fed sample by sample in time order (ROS bags, drivers): add_imu / add_frame, then "
                        "finish() -> RunSummary, as run_euroc gives for a folder")
      .def(py::init<const Config&, double>(), py::arg("config"), py::arg("realtime_speed") = 0.0)
      .def("add_imu", [](StreamRun& r, std::int64_t t_ns, const py::object& acc, const py::object& gyr) {
             r.addImu(t_ns, toVec3(acc, "acc"), toVec3(gyr, "gyr"));
           }, py::arg("t_ns"), py::arg("acc"), py::arg("gyr"))
      .def("add_frame", [](StreamRun& r, std::int64_t t_ns, const py::array& left,
                           const std::optional<py::array>& right, double load_cpu_s) {
             const ImageView l(left, "left");
             std::optional<ImageView> rv;
             if (right) rv.emplace(*right, "right");
             const cv::Mat right_mat = rv ? rv->mat : cv::Mat();
             py::gil_scoped_release release;
             return r.addFrame(t_ns, l.mat, right_mat, load_cpu_s);
           }, py::arg("t_ns"), py::arg("left"), py::arg("right") = py::none(), py::arg("load_cpu_s") = 0.0,
           "A frame (uint8 gray or BGR arrays; right None for mono); load_cpu_s: CPU time spent decoding it")
      .def("add_warning", &StreamRun::addWarning, py::arg("warning"))
      .def("finish", [](StreamRun& r) {
             py::gil_scoped_release release;
             return r.finish();
           })
      .def_property_readonly("frames", &StreamRun::frames);

  m.def("run_euroc", [](const std::string& dataset, const Config& config, int max_frames, double start_s,
                        std::optional<py::function> progress, const std::string& camchain,
                        const std::string& imu_yaml, double realtime_speed) {
          RunOptions opt;
          opt.max_frames = max_frames;
          opt.start_s = start_s;
          opt.open.camchain = camchain;
          opt.open.imu_yaml = imu_yaml;
          opt.realtime_speed = realtime_speed;
          opt.progress = withGil<int, int>(progress);
          py::gil_scoped_release release;
          return runEuroc(dataset, config, opt);
        }, py::arg("dataset"), py::arg("config"), py::arg("max_frames") = -1, py::arg("start_s") = 0.0,
        py::arg("progress") = py::none(), py::arg("camchain") = "", py::arg("imu_yaml") = "",
        py::arg("realtime_speed") = 0.0,
        "Runs a EuRoC folder and returns a RunSummary: blocking and deterministic, or paced by the time stamps at "
        "realtime_speed (> 0, real-time mode: late frames dropped). camchain / imu_yaml: Kalibr files to use "
        "instead of the folder's sensor.yaml.");
}

}  // namespace linnet::python
