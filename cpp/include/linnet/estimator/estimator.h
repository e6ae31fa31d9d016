// The sliding-window stereo-inertial estimator (DESIGN B1; thesis ch. 4-5).
//
// Per frame: preintegrate the IMU to the frame, predict its state, decide whether it is a keyframe, triangulate new
// points, solve the window (prior + IMU + the three point residual kinds, Huber loss) with Ceres, reject outliers,
// detect failures (reset + re-initialise from the last good state, keeping the output continuous), and slide the
// window: marginalise the oldest frame when the second-newest is a keyframe, otherwise drop the second-newest frame's
// visual measurements and merge its preintegration into the newest one's.
//
// Deterministic: single-threaded Ceres, ordered containers; the same inputs give bit-identical outputs as long as
// the solver's time bound (solver.max_solver_time_s) does not bind.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/estimator/estimator_options.h"
#include "linnet/estimator/line_landmarks.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

enum class TrackingStatus { kInitialising, kTracking, kLost };
const char* toString(TrackingStatus s);

struct EstimatorOutput {
  Timestamp t = 0;
  TrackingStatus status = TrackingStatus::kInitialising;
  bool has_pose = false;       // true once initialised (also while dead-reckoning after a failure)
  Pose T_W_B;
  Vec3 v_W = Vec3::Zero(), b_a = Vec3::Zero(), b_g = Vec3::Zero();
  bool keyframe = false;
  int num_points = 0;          // point landmarks used in the last solve
  int num_lines = 0;           // line landmarks used in the last solve
  int reidentified_lines = 0;  // new front-end tracks found to continue a window line this frame (LineLandmarks::
                               // reidentify)
  double line_ms = 0.0;        // back-end wall time of the line-only steps this frame (observe, triangulate, build
                               // residuals, reject outliers, marginalise), ms; the joint solve is in solver_ms
  double solver_ms = 0.0;      // wall time of the window solve (points, lines, IMU, prior), ms
  int reinitialisations = 0;   // so far
  Pose T_B_R;                  // online correction of the rig's extrinsics (cameras at T_B_R * T_B_Ci); identity
                               // unless estimator.extrinsics.estimate
  Pose S_C1;                   // online correction of cam1 relative to cam0 (cam1 at T_B_R * T_B_C1 * S_C1);
                               // identity unless estimator.extrinsics.estimate_stereo
  double time_offset_s = 0.0;  // camera-to-IMU time offset in use (estimator.time_offset), s
  double solve_ms = 0.0;       // back-end wall time for this frame
};

class EstimatorCore;

class Estimator {
 public:
  /// T_B_C1 = nullopt: monocular (stays kInitialising until the mono initialiser exists). Validates the options
  /// (ConfigError naming the key).
  Estimator(const EstimatorOptions& options, const ImuNoise& noise, const Pose& T_B_C0, std::optional<Pose> T_B_C1);
  ~Estimator();
  Estimator(const Estimator&) = delete;
  Estimator& operator=(const Estimator&) = delete;

  /// Adds one IMU sample; time stamps must increase strictly (InputError otherwise).
  void addImu(const ImuSample& s);
  /// Processes one frame; the IMU must have been added up to obs.t. Frame times must increase (UsageError).
  EstimatorOutput addFrame(const FrameObservations& obs);
  /// Triangulated points of the current window, in W.
  std::vector<Vec3> landmarkPositions() const;
  /// The line map: lines that left the window and the window's triangulated lines, finite segments in W.
  std::vector<MapLine> mapLines() const;
  /// The sightings of mapLines()'s lines by id, at the odometry's poses, when estimator.lines.map.adjust keeps them
  /// (for the global adjustment of the line map, LoopCloser::adjustLines); empty otherwise.
  std::map<std::int64_t, std::vector<LineSighting>> mapLineSightings() const;
  /// The window's triangulated lines now (current estimate, finite segments in W), by increasing id.
  std::vector<MapLine> windowLines() const;
  /// The window's frames now (oldest first): time stamp and T_W_B.
  std::vector<std::pair<Timestamp, Pose>> windowPoses() const;
  /// The window's triangulated point landmarks now: track id and position in W, by increasing id.
  std::vector<std::pair<std::int64_t, Vec3>> pointLandmarks() const;

 private:
  std::unique_ptr<EstimatorCore> core_;
};

}  // namespace linnet
