// Runs a EuRoC-format dataset through a System in time order (blocking mode: deterministic), and StreamRun, which
// does the same bookkeeping for data from any other source (ROS bags, a live driver) fed sample by sample.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "linnet/io/euroc_dataset.h"

#include "linnet/pipeline/config.h"
#include "linnet/pipeline/system.h"

namespace linnet {

struct RunOptions {
  int max_frames = -1;         // stop after this many stereo frames (-1: all)
  double start_s = 0.0;        // skip the images of the first start_s seconds (s)
  std::function<void(int done, int total)> progress;  // called after each frame is handed to the System
  EurocOpenOptions open;       // how the folder is read (Kalibr camchain / imu.yaml instead of sensor.yaml, ...)
  double realtime_speed = 0.0;  // > 0: pace the input by its time stamps at this speed (1: real time) in the
                                // config's real-time mode (pipeline.blocking = false: late frames dropped); 0: off
};

struct RunSummary {
  int frames = 0;                 // frames handed to the System
  int processed_frames = 0;       // frames the estimator processed
  int frames_with_pose = 0;       // of which with a pose (initialised)
  int dropped_frames = 0;         // real-time mode drops / frames without IMU coverage
  double init_time_s = -1.0;      // data time from the first image to the first pose (-1: never initialised)
  int reinitialisations = 0;
  double wall_time_s = 0.0;       // wall-clock time of the run (image loading included)
  double sequence_duration_s = 0.0;  // data time spanned by the images that were run
  double real_time_factor = 0.0;  // wall_time_s / sequence_duration_s
  double cpu_time_s = 0.0;        // CPU time of the whole process during the run, every thread (s)
  double cpu_real_time_factor = 0.0;  // cpu_time_s / sequence_duration_s: what the run costs on one core
  double image_load_cpu_s = 0.0;  // CPU time spent reading and decoding the images (s), part of cpu_time_s
  Timestamp first_frame_t = 0, last_frame_t = 0;  // time stamps of the first / last frame handed over (ns)
  Timestamp first_imu_t = 0, last_imu_t = 0;      // of the first / last IMU sample handed over (ns; 0: none)
  int imu_samples = 0;
  bool stereo = true;                     // the run used cam0 + cam1 (false: monocular)
  bool extrinsics_estimated = false;      // estimator.extrinsics.estimate
  Pose extrinsics_correction;             // the last pose's online rig correction T_B_R (cameras at T_B_R * T_B_Ci)
  bool stereo_correction_estimated = false;  // estimator.extrinsics.estimate_stereo (with estimate, stereo runs)
  Pose stereo_correction;                 // the last pose's online correction S of cam1 (at T_B_R * T_B_C1 * S)
  bool time_offset_estimated = false;     // estimator.time_offset.estimate
  double time_offset_s = 0.0;             // the last pose's camera-to-IMU time offset (camera stamp - capture), s
  bool loop_enabled = false;              // loop.enabled (and stereo)
  std::vector<LoopEvent> loops;           // loops closed
  LoopStats loop_stats;                   // the loop closer's keyframes, graph nodes, descriptions and solves
  std::vector<std::string> warnings;      // accepted but worth knowing (the dataset's, and the runner's)
  std::vector<FrameResult> results;
  std::vector<Vec3> map_points;
  std::vector<MapLine> map_lines;     // the published line map (SystemMap::lines)
  LineMapCurationStats line_curation; // the line map before curation, and what it left out
  LineAdjustmentStats line_adjustment; // the line map's global adjustment (estimator.lines.map.adjust)
  long reidentified_lines = 0;  // new line tracks found to continue a window line (estimator.lines.reidentify)
};

/// The config for a EuRoC folder: `base` with cam0/cam1/imu calibration replaced by the dataset's sensor.yaml (or
/// the Kalibr files named in `open`). Without cam1 the config is monocular.
Config configForEuroc(const std::string& dataset_path, const Config& base, const EurocOpenOptions& open = {});

/// The config for a Kalibr calibration: `base` with the cameras of `camchain` (one: monocular, two: stereo) and the
/// IMU noise of `imu_yaml` (empty: keep base's). Camchains hold no frame rate: cameras get `rate_hz`.
Config configForKalibr(const std::string& camchain, const std::string& imu_yaml, double rate_hz, const Config& base);

/// Feeds a System in time order and keeps the run's bookkeeping (frames, IMU span, wall and CPU time), so that every
/// source gives the same RunSummary as runEuroc. Not thread-safe: one producer.
class StreamRun {
 public:
  /// `realtime_speed` as in RunOptions: > 0 paces addImu / addFrame by the data's time stamps (sleeping until each
  /// sample is due) and runs the System in real-time mode.
  explicit StreamRun(const Config& config, double realtime_speed = 0.0);
  ~StreamRun();
  StreamRun(const StreamRun&) = delete;
  StreamRun& operator=(const StreamRun&) = delete;

  /// An IMU sample (body frame, SI); see System::addImu.
  void addImu(Timestamp t, const Vec3& acc, const Vec3& gyr);
  /// A frame: `right` empty for a monocular config. `load_cpu_s` is the CPU time the caller spent reading and
  /// decoding it (reported as image_load_cpu_s). Returns false if the System dropped it (real-time mode).
  bool addFrame(Timestamp t, const cv::Mat& left, const cv::Mat& right, double load_cpu_s = 0.0);
  /// The same, handing the images over (System::addStereo's && overload: a decoded image is not copied again).
  bool addFrame(Timestamp t, cv::Mat&& left, cv::Mat&& right, double load_cpu_s = 0.0);
  /// Processes everything queued and returns the summary (results, map, timings). Once only.
  RunSummary finish();
  int frames() const { return summary_.frames; }
  void addWarning(std::string warning) { summary_.warnings.push_back(std::move(warning)); }
  /// Called for every processed frame on the estimator thread (System::setCallback). Set before adding data.
  void setCallback(std::function<void(const FrameResult&)> callback) { system_->setCallback(std::move(callback)); }

 private:
  Config config_;
  std::unique_ptr<System> system_;
  RunSummary summary_;
  double realtime_speed_ = 0.0;
  Timestamp pace_t0_ = -1;  // data time of the first paced sample
  std::chrono::steady_clock::time_point wall0_;
  double cpu0_ = 0.0;
  bool started_ = false;  // wall0_ / cpu0_ set (at the first sample)
  bool finished_ = false;

  void pace(Timestamp t);
};

/// Runs the dataset. Throws InputError for unreadable data (naming the file), ConfigError for a bad config.
RunSummary runEuroc(const std::string& dataset_path, const Config& config, const RunOptions& options = {});

/// Writes DIR/trajectory.tum (a pose per frame with a pose, body frame, seconds), DIR/trajectory.csv (EuRoC style
/// with velocity and biases), DIR/timing.csv (per frame ms), DIR/map.ply (points and line segments as PLY edges) and
/// DIR/map_lines.csv (`id,x0,y0,z0,x1,y1,z1,observations`, W, metres). Creates DIR.
void writeRunOutputs(const RunSummary& summary, const std::string& out_dir);

}  // namespace linnet
