// The System's per-frame results for the whole run (System::trajectory), kept compactly.
//
// A run keeps one result per frame for as long as it lasts, so on a long flight (or a live run) this is one of the
// few things that grow with time. A FrameResult is 528 bytes; the log keeps 224 per frame (in blocks of 256) and
// gives the same FrameResult back:
// - the odometry state (time, pose, velocity, biases, status, counts) as it is, in double precision;
// - the timing and memory diagnostics in single precision (milliseconds and megabytes: 7 significant digits);
// - the calibration (T_B_R, S_C1, time offset) and the loop correction applied to the System's pose only where they
//   change: they are constant once the online calibration ends and between loops. A frame's corrected pose is the
//   product the estimator thread computed (correction * odometry), recomputed exactly the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/pipeline/system.h"

namespace linnet {

class ResultLog {
 public:
  /// Appends a frame's result. `correction`: the loop correction r.T_W_B = correction * r.estimate.T_W_B was made
  /// with (r.v_W = correction.q * r.estimate.v_W); nullopt when r.T_W_B / r.v_W are the odometry's own.
  void push(const FrameResult& r, const std::optional<Pose>& correction);

  std::size_t size() const { return size_; }
  /// The i-th result as pushed (timings and memory rounded to single precision).
  FrameResult at(std::size_t i) const;
  /// Replaces the correction of every frame with an odometry pose by final(t) (the pose graph's final one, at the end
  /// of the stream). `final` is called in time order.
  void recorrect(const std::function<Pose(Timestamp)>& final);

  /// Heap memory held by the log, bytes (approximate: the deque's blocks and the change lists).
  std::size_t bytes() const;

 private:
  struct Record {
    Pose T_W_B;  // the odometry's (EstimatorOutput::T_W_B)
    Timestamp t = 0;
    Vec3 v_W = Vec3::Zero(), b_a = Vec3::Zero(), b_g = Vec3::Zero();
    std::int32_t num_points = 0, num_lines = 0, reidentified_lines = 0, reinitialisations = 0;
    std::int32_t tracked_points = 0, stereo_points = 0, tracked_lines = 0;
    std::uint8_t status = 0;
    bool has_pose = false, keyframe = false, corrected = false;
    // EstimatorOutput::line_ms, solver_ms, solve_ms; FrameResult::point_ms, line_ms, frontend_ms, backend_ms,
    // point_cpu_ms, line_cpu_ms, backend_cpu_ms, loop_cpu_ms, rss_mb
    float est_line_ms = 0, est_solver_ms = 0, est_solve_ms = 0;
    float point_ms = 0, line_ms = 0, frontend_ms = 0, backend_ms = 0;
    float point_cpu_ms = 0, line_cpu_ms = 0, backend_cpu_ms = 0, loop_cpu_ms = 0, rss_mb = 0;
  };
  struct Calibration {
    Pose T_B_R, S_C1;
    double time_offset_s = 0.0;
  };
  static bool samePose(const Pose& a, const Pose& b);
  // The entry in force at record i of a list of (first record, value) sorted by first record.
  template <class T>
  static const T* inForce(const std::vector<std::pair<std::size_t, T>>& list, std::size_t i);

  // The records in blocks of kBlock, allocated as the log grows: a frame costs sizeof(Record) (224 bytes). A
  // std::deque kept two records per 512-byte block, about 264 bytes a frame with the allocator's headers.
  static constexpr std::size_t kBlock = 256;
  const Record& record(std::size_t i) const { return blocks_[i / kBlock][i % kBlock]; }
  std::vector<std::unique_ptr<Record[]>> blocks_;
  std::size_t size_ = 0;
  std::vector<std::pair<std::size_t, Calibration>> calibrations_;  // from which record on
  // The corrections of the records with corrected set, from which record on (after recorrect(): of every record with
  // an odometry pose).
  std::vector<std::pair<std::size_t, Pose>> corrections_;
  bool recorrected_ = false;
};

}  // namespace linnet
