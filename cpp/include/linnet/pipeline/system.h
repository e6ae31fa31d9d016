// System: the public C++ API of Linnet (DESIGN A2).
//
//   linnet::System sys(linnet::Config::eurocStereoImu());
//   sys.setCallback([](const linnet::FrameResult& r) { ... });
//   sys.addImu(t, acc, gyr); ...; sys.addStereo(t, left, right); ...
//   sys.finish();
//   for (const auto& r : sys.trajectory()) ...
//
// Stages: front-end (point worker + line worker, in parallel) -> estimator, joined by bounded queues with an
// end-of-stream marker. In blocking mode nothing is dropped and a run is deterministic; in real-time mode a frame
// that finds the front-end queue full is dropped (addStereo returns false).
// Threading: add* may be called from any one producer thread; the callback runs on the estimator thread.
#pragma once

#include <atomic>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/estimator/estimator.h"
#include "linnet/estimator/line_map_curation.h"
#include "linnet/loop/loop_closer.h"
#include "linnet/pipeline/config.h"

namespace linnet {

/// The 3D map: the window's point landmarks and the line map (lines that left the window stay), in W (loop-corrected
/// when loop closure is on: each line by the correction at its last observation). The lines are the published ones:
/// those within estimator.lines.map's sigma bound (line_map_curation.h).
struct SystemMap {
  std::vector<Vec3> points;
  std::vector<MapLine> lines;
  LineMapCurationStats line_curation;  // how many lines the map held, and why some are not published
  LineAdjustmentStats line_adjustment; // the global adjustment of the line map (estimator.lines.map.adjust)
};

/// Everything the System reports for one processed frame.
struct FrameResult {
  EstimatorOutput estimate;  // the odometry (the estimator's output, never changed by loop closure)
  // The System's pose: the odometry mapped into the loop-corrected world (config.loop). In the callback, with the
  // correction known at that time; in trajectory() after finish(), with the final correction of the frame's
  // keyframe. Equal to estimate.T_W_B / v_W when loop closure is off or has found no loop.
  Pose T_W_B;
  Vec3 v_W = Vec3::Zero();
  int tracked_points = 0;  // points delivered by the front-end
  int stereo_points = 0;   // of which matched in the right image
  int tracked_lines = 0;   // lines delivered by the front-end
  double point_ms = 0.0;     // point worker
  double line_ms = 0.0;      // line worker
  double frontend_ms = 0.0;  // front-end wall time (max of the two workers when parallel)
  double backend_ms = 0.0;   // estimator wall time
  double line_backend_ms = 0.0;  // of which the line-only steps (EstimatorOutput::line_ms)
  double solver_ms = 0.0;        // of which the window solve
  // CPU time of the same stages (thread CPU clock): what each stage costs, whatever else shares the core
  double point_cpu_ms = 0.0;
  double line_cpu_ms = 0.0;
  double backend_cpu_ms = 0.0;
  double loop_cpu_ms = 0.0;  // loop closer (keyframes only)
  double rss_mb = 0.0;       // the process's resident set size after the frame, MB (memory growth on long runs)
};

class System {
 public:
  /// Validates the config (ConfigError naming the key) and starts the worker threads.
  explicit System(const Config& config);
  ~System();
  System(const System&) = delete;
  System& operator=(const System&) = delete;

  /// An IMU sample (body frame, SI). Time stamps must increase strictly (UsageError otherwise). Never blocks.
  void addImu(Timestamp t, const Vec3& acc, const Vec3& gyr);
  /// A stereo pair (8-bit gray, or BGR converted to gray), of the calibrated size. Returns false if dropped
  /// (real-time mode only). Throws UsageError on a wrong size / type / non-increasing time stamp, and rethrows any
  /// error raised by a worker thread.
  bool addStereo(Timestamp t, const cv::Mat& left, const cv::Mat& right);
  /// A monocular image (config.stereo must be false).
  bool addMono(Timestamp t, const cv::Mat& image);
  /// The same, handing the images over (they are left empty). The const& overloads copy the pixels, as the caller
  /// may write into them once the call returns; a handed-over gray image that no other cv::Mat shares (a freshly
  /// decoded one) is kept as it is.
  bool addStereo(Timestamp t, cv::Mat&& left, cv::Mat&& right);
  bool addMono(Timestamp t, cv::Mat&& image);

  /// Called once per processed frame, in time order, on the estimator thread. Set before adding data.
  void setCallback(std::function<void(const FrameResult&)> callback);

  /// End of stream: processes everything queued, then stops the threads. Idempotent. Rethrows worker errors.
  void finish();

  /// Results of every processed frame so far, in time order.
  std::vector<FrameResult> trajectory() const;
  /// The map (window points, all good lines), in W; empty until finish().
  SystemMap map() const;
  /// Frames dropped in real-time mode (or frames the IMU never covered).
  int droppedFrames() const { return dropped_.load(); }
  /// Loops closed so far (empty when config.loop is off); complete after finish().
  std::vector<LoopEvent> loops() const;
  /// The loop closer's keyframe and graph counts (zeros when config.loop is off); complete after finish().
  LoopStats loopStats() const;
  const Config& config() const { return config_; }

 private:
  struct Impl;
  bool addFrame(Timestamp t, cv::Mat&& left, cv::Mat&& right);
  void rethrowWorkerError();

  Config config_;
  std::unique_ptr<Impl> impl_;
  std::atomic<int> dropped_{0};
};

}  // namespace linnet
