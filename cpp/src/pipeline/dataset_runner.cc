#include "linnet/pipeline/dataset_runner.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>
#include <utility>

#include "linnet/core/cpu_clock.h"
#include "linnet/core/error.h"
#include "linnet/io/config_yaml.h"
#include "linnet/io/euroc_dataset.h"
#include "linnet/io/map_io.h"
#include "linnet/io/trajectory_io.h"

namespace linnet {

Config configForEuroc(const std::string& dataset_path, const Config& base, const EurocOpenOptions& open) {
  EurocOpenOptions o = open;
  o.load_ground_truth = false;
  const EurocDataset ds = EurocDataset::open(dataset_path, o);
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

Config configForKalibr(const std::string& camchain, const std::string& imu_yaml, double rate_hz, const Config& base) {
  if (!(rate_hz > 0.0)) throw UsageError("configForKalibr: rate_hz must be > 0");
  const KalibrCamchain chain = readKalibrCamchain(camchain);
  Config c = base;
  c.cam0 = chain.cameras.at(0);
  c.cam0.rate_hz = rate_hz;
  c.stereo = chain.cameras.size() >= 2;
  if (c.stereo) {
    c.cam1 = chain.cameras[1];
    c.cam1.rate_hz = rate_hz;
  }
  if (!imu_yaml.empty()) {
    c.imu = readImuSensorYaml(imu_yaml);
    c.imu.gravity = base.imu.gravity;
  }
  c.validate();
  return c;
}

namespace {

std::string seconds(Timestamp t) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.3f s", toSeconds(t));
  return buf;
}

/// " (the image time stamps look like ms)" when images and IMU differ by a factor of 1e3 / 1e6 / 1e9, else "".
std::string unitHint(Timestamp image_t, Timestamp imu_t) {
  if (image_t <= 0 || imu_t <= 0) return "";
  const double ratio = static_cast<double>(imu_t) / static_cast<double>(image_t);
  const struct { double factor; const char* unit; } units[] = {{1e3, "us"}, {1e6, "ms"}, {1e9, "s"}};
  for (const auto& u : units)
    if (ratio > 0.3 * u.factor && ratio < 3.0 * u.factor)
      return std::string(" (the image time stamps look like ") + u.unit + ")";
  for (const auto& u : units)
    if (ratio * u.factor > 0.3 && ratio * u.factor < 3.0)
      return std::string(" (the IMU time stamps look like ") + u.unit + ")";
  return "";
}

/// The frames [first, last) to run: after start_s, at most max_frames, and only those the IMU log covers (a warning
/// names the files and the times when it does not cover them all; an InputError when it covers none).
std::pair<std::size_t, std::size_t> selectFrames(const EurocDataset& ds, const RunOptions& options,
                                                 std::vector<std::string>* warnings) {
  const auto& frames = ds.frames();
  const auto& imu = ds.imu();
  const std::string imu_csv = ds.root() + "/imu0/data.csv", cam_csv = ds.root() + "/cam0/data.csv";
  const Timestamp t_first = frames.front().t + fromSeconds(options.start_s);
  std::size_t first = 0;
  while (first < frames.size() && frames[first].t < t_first) ++first;
  std::size_t last = frames.size();
  if (options.max_frames >= 0) last = std::min(last, first + static_cast<std::size_t>(options.max_frames));
  if (first >= last) throw UsageError("no frames selected (start_s / max_frames leave nothing to run)");

  const Timestamp imu0 = imu.front().t, imu1 = imu.back().t;
  if (frames[first].t > imu1 || frames[last - 1].t < imu0)
    throw InputError(cam_csv, 0,
                     "no image lies in the IMU log's time span: images " + seconds(frames[first].t) + " to " +
                         seconds(frames[last - 1].t) + ", IMU (" + imu_csv + ") " + seconds(imu0) + " to " +
                         seconds(imu1) + "; both must be in ns on the same clock" +
                         unitHint(frames[first].t, imu0));
  std::size_t covered = last;
  while (covered > first && frames[covered - 1].t > imu1) --covered;
  if (covered < last) {
    warnings->push_back(imu_csv + " ends at " + seconds(imu1) + ", before the last image (" +
                        seconds(frames[last - 1].t) + "): the " + std::to_string(last - covered) +
                        " images after it are not run");
    last = covered;
  }
  std::size_t begin = first;
  while (begin < last && frames[begin].t < imu0) ++begin;
  if (begin > first)
    warnings->push_back(imu_csv + " starts at " + seconds(imu0) + ", after the first image (" +
                        seconds(frames[first].t) + "): the " + std::to_string(begin - first) +
                        " images before it are not run");
  return {begin, last};
}

void checkImageSize(const cv::Mat& image, const CameraCalibration& calib, const std::string& path, const char* cam) {
  if (image.cols != calib.width || image.rows != calib.height)
    throw InputError(path, 0,
                     "image is " + std::to_string(image.cols) + "x" + std::to_string(image.rows) + ", the " + cam +
                         " calibration says " + std::to_string(calib.width) + "x" + std::to_string(calib.height));
}

}  // namespace

StreamRun::StreamRun(const Config& config, double realtime_speed)
    : config_(config), realtime_speed_(realtime_speed) {
  if (realtime_speed_ < 0.0) throw UsageError("realtime speed must be >= 0 (0: as fast as possible)");
  if (realtime_speed_ > 0.0) config_.pipeline.blocking = false;
  system_ = std::make_unique<System>(config_);
  summary_.stereo = config_.stereo;
  summary_.extrinsics_estimated = config_.estimator.extrinsics.estimate;
  summary_.stereo_correction_estimated =
      config_.estimator.extrinsics.estimate && config_.estimator.extrinsics.estimate_stereo && config_.stereo;
  summary_.time_offset_estimated = config_.estimator.time_offset.estimate;
}

StreamRun::~StreamRun() = default;

void StreamRun::pace(Timestamp t) {
  if (!started_) {  // the run's wall and CPU clocks start with its first sample (a live source may wait for data)
    started_ = true;
    wall0_ = std::chrono::steady_clock::now();
    cpu0_ = processCpuSeconds();
  }
  if (realtime_speed_ <= 0.0) return;
  if (pace_t0_ < 0) {
    pace_t0_ = t;
    wall0_ = std::chrono::steady_clock::now();
    return;
  }
  const double due_s = toSeconds(t - pace_t0_) / realtime_speed_;
  std::this_thread::sleep_until(wall0_ + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                             std::chrono::duration<double>(due_s)));
}

void StreamRun::addImu(Timestamp t, const Vec3& acc, const Vec3& gyr) {
  pace(t);
  system_->addImu(t, acc, gyr);
  if (summary_.imu_samples == 0) summary_.first_imu_t = t;
  summary_.last_imu_t = t;
  ++summary_.imu_samples;
}

bool StreamRun::addFrame(Timestamp t, const cv::Mat& left, const cv::Mat& right, double load_cpu_s) {
  cv::Mat l = left, r = right;  // headers shared with the caller's: the System copies their pixels
  return addFrame(t, std::move(l), std::move(r), load_cpu_s);
}

bool StreamRun::addFrame(Timestamp t, cv::Mat&& left, cv::Mat&& right, double load_cpu_s) {
  if (finished_) throw UsageError("StreamRun: addFrame after finish");
  pace(t);
  summary_.image_load_cpu_s += load_cpu_s;
  bool accepted = false;
  if (config_.stereo) {
    if (right.empty()) throw UsageError("StreamRun: a stereo config needs the right image of every frame");
    accepted = system_->addStereo(t, std::move(left), std::move(right));
  } else {
    accepted = system_->addMono(t, std::move(left));
  }
  if (summary_.frames == 0) summary_.first_frame_t = t;
  summary_.last_frame_t = t;
  ++summary_.frames;
  return accepted;
}

RunSummary StreamRun::finish() {
  if (finished_) throw UsageError("StreamRun: finish called twice");
  finished_ = true;
  system_->finish();
  RunSummary summary = std::move(summary_);
  summary.results = system_->trajectory();
  SystemMap map = system_->map();
  summary.map_points = std::move(map.points);
  summary.map_lines = std::move(map.lines);
  summary.line_curation = map.line_curation;
  summary.line_adjustment = map.line_adjustment;
  for (const FrameResult& r : summary.results) summary.reidentified_lines += r.estimate.reidentified_lines;
  summary.dropped_frames = system_->droppedFrames();
  summary.loop_enabled = config_.loop.enabled && config_.stereo;
  summary.loops = system_->loops();
  summary.loop_stats = system_->loopStats();
  summary.processed_frames = static_cast<int>(summary.results.size());
  for (const FrameResult& r : summary.results) {
    if (r.estimate.has_pose) {
      if (summary.frames_with_pose == 0) summary.init_time_s = toSeconds(r.estimate.t - summary.first_frame_t);
      ++summary.frames_with_pose;
    }
    summary.reinitialisations = std::max(summary.reinitialisations, r.estimate.reinitialisations);
    if (r.estimate.has_pose) {
      summary.extrinsics_correction = r.estimate.T_B_R;
      summary.stereo_correction = r.estimate.S_C1;
      summary.time_offset_s = r.estimate.time_offset_s;
    }
  }
  if (!started_) pace(0);
  summary.wall_time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
  if (summary.frames > 0)
    summary.sequence_duration_s =
        toSeconds(summary.last_frame_t - summary.first_frame_t) + 1.0 / config_.cam0.rate_hz;
  if (summary.sequence_duration_s > 0.0) {
    summary.real_time_factor = summary.wall_time_s / summary.sequence_duration_s;
    summary.cpu_time_s = processCpuSeconds() - cpu0_;
    summary.cpu_real_time_factor = summary.cpu_time_s / summary.sequence_duration_s;
  }
  return summary;
}

RunSummary runEuroc(const std::string& dataset_path, const Config& config, const RunOptions& options) {
  EurocOpenOptions open = options.open;
  open.use_cam1 = open.use_cam1 && config.stereo;
  open.read_calibration = false;  // the calibration is the config's; the folder gives the data (and Kalibr time shift)
  const EurocDataset ds = EurocDataset::open(dataset_path, open);
  const auto& frames = ds.frames();
  const auto& imu = ds.imu();
  if (frames.empty()) throw InputError(dataset_path, 0, "the dataset has no images");
  if (imu.empty()) throw InputError(dataset_path, 0, "the dataset has no IMU samples");
  if (config.stereo && !ds.stereo())
    throw ConfigError("config key 'stereo': the config is stereo but " + dataset_path +
                                    " has no cam1 (set stereo: false for a monocular run)");
  std::vector<std::string> warnings = ds.warnings();
  if (!config.stereo) {
    std::error_code ec;
    const bool has_cam1 = std::filesystem::exists(std::filesystem::path(ds.root()) / "cam1" / "data.csv", ec);
    warnings.push_back(std::string("monocular run: ") +
                       (has_cam1 ? "the config sets stereo: false" : "the dataset has no cam1/data.csv") +
                       " (monocular + IMU initialisation is not available yet: give a stereo dataset)");
  }
  const auto [first, last] = selectFrames(ds, options, &warnings);

  StreamRun run(config, options.realtime_speed);
  for (std::string& w : warnings) run.addWarning(std::move(w));
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
      run.addImu(imu[k].t, imu[k].acc, imu[k].gyr);
      const bool covers = imu[k].t >= f.t;
      ++k;
      if (covers) break;
    }
    const double load0 = threadCpuMs();
    cv::Mat left = EurocDataset::loadImage(f.left_path);
    cv::Mat right;
    if (config.stereo) {
      if (f.right_path.empty()) throw InputError(f.left_path, 0, "no right image pairs with this left image");
      right = EurocDataset::loadImage(f.right_path);
    }
    checkImageSize(left, config.cam0, f.left_path, "cam0");
    if (config.stereo) checkImageSize(right, config.cam1, f.right_path, "cam1");
    run.addFrame(f.t, std::move(left), std::move(right), 1e-3 * (threadCpuMs() - load0));
    if (options.progress) options.progress(run.frames(), total);
  }
  // A few IMU samples past the last frame, so it is covered.
  for (int extra = 0; extra < 4 && k < imu.size(); ++extra, ++k) run.addImu(imu[k].t, imu[k].acc, imu[k].gyr);
  return run.finish();
}

namespace {

// loops.csv: one row per loop closed, with the measured relative pose of the two keyframes' bodies.
void writeLoopsCsv(const std::string& path, const std::vector<LoopEvent>& loops) {
  std::string text =
      "#t_new [ns],t_old [ns],inliers,correction [m],correction_yaw [deg],x [m],y [m],z [m],qx,qy,qz,qw "
      "(T_old_new: the new keyframe's body in the old one's, as measured),sigma [m],sigma_yaw [deg] (its edge's),"
      "method (descriptors / guided / lines: how it was verified)\n";
  for (const LoopEvent& e : loops) {
    const Quat q = e.T_old_new.q.normalized();
    text += std::to_string(e.t_new) + "," + std::to_string(e.t_old) + "," + std::to_string(e.inliers);
    for (const double v : {e.correction_m, e.correction_yaw_deg, e.T_old_new.p.x(), e.T_old_new.p.y(),
                           e.T_old_new.p.z(), q.x(), q.y(), q.z(), q.w(), e.sigma_m, e.sigma_yaw_deg})
      text.append(",").append(io::formatDouble(v));
    text.append(",").append(placeMatchMethodName(e.method)).append("\n");
  }
  writeTextFile(path, text);
}

}  // namespace

void writeRunOutputs(const RunSummary& summary, const std::string& out_dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (ec) throw InputError(out_dir, 0, "cannot create the output folder: " + ec.message());
  // The System's poses (loop-corrected when loop closure is on), or the odometry (the estimator's own output).
  auto states = [&](bool odometry) {
    std::vector<TrajectoryState> out;
    for (const FrameResult& r : summary.results) {
      if (!r.estimate.has_pose) continue;
      TrajectoryState s;
      s.t = r.estimate.t;
      s.T_W_B = odometry ? r.estimate.T_W_B : r.T_W_B;
      s.v_W = odometry ? r.estimate.v_W : r.v_W;
      s.b_a = r.estimate.b_a;
      s.b_g = r.estimate.b_g;
      out.push_back(s);
    }
    return out;
  };
  writeTum((fs::path(out_dir) / "trajectory.tum").string(), states(false));
  if (summary.loop_enabled) writeTum((fs::path(out_dir) / "odometry.tum").string(), states(true));
  writeEurocCsv((fs::path(out_dir) / "trajectory.csv").string(), states(false));
  MapGeometry map;
  map.points = summary.map_points;
  for (const MapLine& l : summary.map_lines) map.segments.push_back(Segment3{l.a, l.b});
  writePly((fs::path(out_dir) / "map.ply").string(), map);
  writeMapLinesCsv((fs::path(out_dir) / "map_lines.csv").string(), summary.map_lines);
  if (summary.loop_enabled) writeLoopsCsv((fs::path(out_dir) / "loops.csv").string(), summary.loops);

  const std::string timing_path = (fs::path(out_dir) / "timing.csv").string();
  std::FILE* f = std::fopen(timing_path.c_str(), "w");
  if (f == nullptr) throw InputError(timing_path, 0, "cannot write");
  std::fprintf(f, "#timestamp [ns],frontend_ms,backend_ms,total_ms,point_ms,line_ms,points,stereo_points,lines,"
                  "keyframe,status,point_cpu_ms,line_cpu_ms,backend_cpu_ms,line_backend_ms,solver_ms,"
                  "landmark_points,landmark_lines,loop_cpu_ms,rss_mb\n");
  for (const FrameResult& r : summary.results) {
    std::fprintf(f, "%lld,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%d,%d,%d,%.3f,%.3f,%.3f,%.3f,%.3f,%d,%d,%.3f,%.1f\n",
                 static_cast<long long>(r.estimate.t), r.frontend_ms, r.backend_ms, r.frontend_ms + r.backend_ms,
                 r.point_ms, r.line_ms, r.tracked_points, r.stereo_points, r.tracked_lines,
                 r.estimate.keyframe ? 1 : 0, static_cast<int>(r.estimate.status), r.point_cpu_ms, r.line_cpu_ms,
                 r.backend_cpu_ms, r.line_backend_ms, r.solver_ms, r.estimate.num_points, r.estimate.num_lines, r.loop_cpu_ms,
                 r.rss_mb);
  }
  std::fclose(f);
}

}  // namespace linnet
