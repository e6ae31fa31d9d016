#include "linnet/pipeline/dataset_runner.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "linnet/core/cpu_clock.h"
#include "linnet/core/error.h"
#include "linnet/io/euroc_dataset.h"
#include "linnet/io/map_io.h"
#include "linnet/io/trajectory_io.h"

namespace linnet {

Config configForEuroc(const std::string& dataset_path, const Config& base) {
  const EurocDataset ds = EurocDataset::open(dataset_path);
  Config c = base;
  c.cam0 = ds.cam0();
  if (ds.cam1() != nullptr) {
    c.cam1 = *ds.cam1();
  } else {
    c.stereo = false;
  }
  c.imu = ds.imuNoise();
  c.imu.gravity = base.imu.gravity;
  c.validate();
  return c;
}

RunSummary runEuroc(const std::string& dataset_path, const Config& config, const RunOptions& options) {
  const auto wall0 = std::chrono::steady_clock::now();
  const double cpu0 = processCpuSeconds();
  const EurocDataset ds = EurocDataset::open(dataset_path);
  const auto& frames = ds.frames();
  const auto& imu = ds.imu();
  if (frames.empty()) throw InputError(dataset_path, 0, "the dataset has no images");
  if (imu.empty()) throw InputError(dataset_path, 0, "the dataset has no IMU samples");

  // Select the frames to run.
  const Timestamp t_first = frames.front().t + fromSeconds(options.start_s);
  std::size_t first = 0;
  while (first < frames.size() && frames[first].t < t_first) ++first;
  std::size_t last = frames.size();
  if (options.max_frames >= 0) last = std::min(last, first + static_cast<std::size_t>(options.max_frames));
  if (first >= last) throw UsageError("no frames selected (start_s / max_frames leave nothing to run)");

  RunSummary summary;
  System system(config);
  const int total = static_cast<int>(last - first);
  // IMU from before the first frame: the estimator's stillness test and gravity alignment look back
  // estimator.init.gravity_window_s from the first image.
  std::size_t k = 0;
  const Timestamp imu_start = frames[first].t - fromSeconds(config.estimator.init.gravity_window_s + 0.05);
  while (k < imu.size() && imu[k].t < imu_start) ++k;

  for (std::size_t i = first; i < last; ++i) {
    const StereoFrameRef& f = frames[i];
    // Every IMU sample up to and including the first one at or after the frame time.
    while (k < imu.size()) {
      system.addImu(imu[k].t, imu[k].acc, imu[k].gyr);
      const bool covers = imu[k].t >= f.t;
      ++k;
      if (covers) break;
    }
    const double load0 = threadCpuMs();
    const cv::Mat left = EurocDataset::loadImage(f.left_path);
    if (config.stereo) {
      if (f.right_path.empty()) throw InputError(f.left_path, 0, "no right image pairs with this left image");
      const cv::Mat right = EurocDataset::loadImage(f.right_path);
      summary.image_load_cpu_s += 1e-3 * (threadCpuMs() - load0);
      system.addStereo(f.t, left, right);
    } else {
      summary.image_load_cpu_s += 1e-3 * (threadCpuMs() - load0);
      system.addMono(f.t, left);
    }
    ++summary.frames;
    if (options.progress) options.progress(summary.frames, total);
  }
  // A few IMU samples past the last frame, so it is covered.
  for (int extra = 0; extra < 4 && k < imu.size(); ++extra, ++k) system.addImu(imu[k].t, imu[k].acc, imu[k].gyr);
  system.finish();

  summary.results = system.trajectory();
  SystemMap map = system.map();
  summary.map_points = std::move(map.points);
  summary.map_lines = std::move(map.lines);
  summary.dropped_frames = system.droppedFrames();
  summary.processed_frames = static_cast<int>(summary.results.size());
  for (const FrameResult& r : summary.results) {
    if (r.estimate.has_pose) {
      if (summary.frames_with_pose == 0) summary.init_time_s = toSeconds(r.estimate.t - frames[first].t);
      ++summary.frames_with_pose;
    }
    summary.reinitialisations = std::max(summary.reinitialisations, r.estimate.reinitialisations);
  }
  summary.wall_time_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  summary.sequence_duration_s = toSeconds(frames[last - 1].t - frames[first].t) + 1.0 / config.cam0.rate_hz;
  summary.real_time_factor = summary.wall_time_s / summary.sequence_duration_s;
  summary.cpu_time_s = processCpuSeconds() - cpu0;
  summary.cpu_real_time_factor = summary.cpu_time_s / summary.sequence_duration_s;
  return summary;
}

void writeRunOutputs(const RunSummary& summary, const std::string& out_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw InputError(out_dir, 0, "cannot create the output folder: " + ec.message());
  std::vector<TrajectoryState> states;
  for (const FrameResult& r : summary.results) {
    if (!r.estimate.has_pose) continue;
    TrajectoryState s;
    s.t = r.estimate.t;
    s.T_W_B = r.estimate.T_W_B;
    s.v_W = r.estimate.v_W;
    s.b_a = r.estimate.b_a;
    s.b_g = r.estimate.b_g;
    states.push_back(s);
  }
  writeTum((fs::path(out_dir) / "trajectory.tum").string(), states);
  writeEurocCsv((fs::path(out_dir) / "trajectory.csv").string(), states);
  MapGeometry map;
  map.points = summary.map_points;
  for (const MapLine& l : summary.map_lines) map.segments.push_back(Segment3{l.a, l.b});
  writePly((fs::path(out_dir) / "map.ply").string(), map);
  writeMapLinesCsv((fs::path(out_dir) / "map_lines.csv").string(), summary.map_lines);

  const std::string timing_path = (fs::path(out_dir) / "timing.csv").string();
  std::FILE* f = std::fopen(timing_path.c_str(), "w");
  if (f == nullptr) throw InputError(timing_path, 0, "cannot write");
  std::fprintf(f, "#timestamp [ns],frontend_ms,backend_ms,total_ms,point_ms,line_ms,points,stereo_points,lines,"
                  "keyframe,status,point_cpu_ms,line_cpu_ms,backend_cpu_ms,line_backend_ms,solver_ms,"
                  "landmark_points,landmark_lines\n");
  for (const FrameResult& r : summary.results) {
    std::fprintf(f, "%lld,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d\n",
                 static_cast<long long>(r.estimate.t), r.frontend_ms, r.backend_ms, r.frontend_ms + r.backend_ms,
                 r.point_ms, r.line_ms, r.tracked_points, r.stereo_points, r.tracked_lines,
                 r.estimate.keyframe ? 1 : 0, static_cast<int>(r.estimate.status), r.point_cpu_ms, r.line_cpu_ms,
                 r.backend_cpu_ms, r.line_backend_ms, r.solver_ms, r.estimate.num_points, r.estimate.num_lines);
  }
  std::fclose(f);
}

}  // namespace linnet
