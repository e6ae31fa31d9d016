// Loop closure for the stereo-inertial odometry (DESIGN A1 "loop"): a keyframe database, loop detection with
// geometric verification, and a 4-DoF pose graph that corrects the trajectory and the map.
//
// Detection: the odometry's drift is small (a fraction of a percent of the path), so a place seen before is
// searched among the old keyframes near the new keyframe's position as corrected so far, within a radius that grows
// with the path travelled since, and with a similar viewing direction. Each candidate (nearest first) is verified by
// ORB descriptor matching and PnP RANSAC against the old keyframe's stereo points (place_matcher.h). A verified loop
// adds an edge to the pose graph (pose_graph.h), which is then solved. The odometry itself is not changed: the loop
// closer keeps T_Wcorrected_Wodometry per keyframe, which maps odometry poses and map elements of that time into the
// corrected world (the drift correction of VINS-Mono, sec. VIII).
//
// The search does not relocalise a lost tracker (that needs place recognition without a position prior, e.g. a bag
// of binary words); it closes loops while the odometry runs.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/loop/loop_options.h"
#include "linnet/loop/place_matcher.h"
#include "linnet/loop/pose_graph.h"

namespace linnet {

struct LoopEvent {
  Timestamp t_new = 0, t_old = 0;  // keyframe times
  int inliers = 0;
  double correction_m = 0.0;       // position change of the new keyframe by the pose-graph solve, m
  double correction_yaw_deg = 0.0; // its yaw change, deg
};

class LoopCloser {
 public:
  /// cam0 (kept by reference: it must outlive the loop closer), T_B_C0 and T_C1_C0 from the calibration.
  LoopCloser(const LoopOptions& options, const CameraModel& cam0, const Pose& T_B_C0, const Pose& T_C1_C0);

  /// A new keyframe at its odometry pose, with its left image and tracked corners. Returns true if it closed a loop.
  bool addKeyframe(Timestamp t, const Pose& T_W_B, const cv::Mat& left, const std::vector<PointObservation>& points);

  /// T_Wcorrected_Wodometry in force at time t: the correction of the last keyframe at or before t (identity before
  /// the first keyframe).
  Pose correctionAt(Timestamp t) const;
  /// The correction of the newest keyframe.
  Pose latestCorrection() const;

  const std::vector<LoopEvent>& loops() const { return loops_; }
  std::size_t keyframes() const { return keyframes_.size(); }

 private:
  struct Keyframe {
    Timestamp t = 0;
    PlaceFeatures place;
    double path_m = 0.0;  // odometry path length up to this keyframe
  };
  bool tryLoop(std::size_t new_index);

  LoopOptions options_;
  const CameraModel& cam0_;
  Pose T_B_C0_, T_C1_C0_;
  std::vector<Keyframe> keyframes_;
  PoseGraph graph_;
  std::vector<LoopEvent> loops_;
  std::size_t last_loop_index_ = 0;
  bool any_loop_ = false;
};

}  // namespace linnet
