// Internal state machine behind linnet::Estimator (not installed; see estimator.h for the contract).
// estimator.cc: frame flow, initialisation, failure handling. estimator_solve.cc: problem building, solving,
// marginalisation / window sliding.
#pragma once

#include <array>
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include <ceres/loss_function.h>

#include "linnet/estimator/estimator.h"
#include "linnet/estimator/factors/prior_factor.h"
#include "linnet/estimator/line_landmarks.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/point_landmarks.h"
#include "linnet/estimator/residual_spec.h"
#include "linnet/estimator/window.h"
#include "linnet/imu/imu_buffer.h"

namespace linnet {

/// Adds the wall time of its scope to a counter, ms.
class ScopedMs {
 public:
  explicit ScopedMs(double* acc) : acc_(acc), t0_(std::chrono::steady_clock::now()) {}
  ~ScopedMs() { *acc_ += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0_).count(); }
  ScopedMs(const ScopedMs&) = delete;
  ScopedMs& operator=(const ScopedMs&) = delete;

 private:
  double* acc_;
  std::chrono::steady_clock::time_point t0_;
};

/// A full navigation state at one time.
using NavState = ImuState;

class EstimatorCore {
 public:
  EstimatorCore(const EstimatorOptions& options, const ImuNoise& noise, const Pose& T_B_C0,
                std::optional<Pose> T_B_C1);

  void addImu(const ImuSample& s);
  EstimatorOutput addFrame(const FrameObservations& obs);
  std::vector<Vec3> landmarkPositions() const { return points_.positions(window_); }
  std::vector<MapLine> mapLines() const { return lines_.mapLines(&window_); }
  std::map<std::int64_t, std::vector<LineSighting>> mapLineSightings() const { return lines_.mapSightings(window_); }
  std::vector<MapLine> windowLines() const { return lines_.windowLines(); }
  std::vector<std::pair<Timestamp, Pose>> windowPoses() const {
    std::vector<std::pair<Timestamp, Pose>> out;
    for (int i = 0; i < window_.size(); ++i) out.emplace_back(window_[i].t, window_[i].T_W_B());
    return out;
  }
  std::vector<std::pair<std::int64_t, Vec3>> pointLandmarks() const {
    std::vector<std::pair<std::int64_t, Vec3>> out;
    for (const auto& [id, lm] : points_.all())
      if (lm.triangulated && window_.find(lm.host) != nullptr) out.emplace_back(id, points_.worldPosition(window_, lm));
    return out;
  }

 private:
  enum class Mode { kWaitingForFirstFrame, kCollecting, kTracking };

  // --- estimator.cc
  /// Starts a new window at `obs` from the state `start` (pose, velocity, biases). velocity_sigma > 0: the velocity
  /// is known to that std (static start, re-initialisation) and tracking begins at once if the frame has enough
  /// stereo points (returns true); <= 0: moving start, frames are collected first.
  bool startWindow(const FrameObservations& obs, const NavState& start, double velocity_sigma);
  void addInitialPrior(double velocity_sigma);
  /// The state to start the first window from: gravity-aligned attitude, gyro bias / zero velocity when static.
  NavState firstState(Timestamp t, bool* is_static) const;
  /// Moving initialisation: PnP pose of the newest frame; after init.moving_frames, gyro bias + velocities.
  bool collectStep(const FrameObservations& obs);
  bool finishMovingInit();
  /// A new window frame at obs.t, its preintegration from the newest frame and the IMU-predicted state.
  WindowFrame& pushPredicted(Timestamp t);
  NavState predictFrom(const WindowFrame& f, Timestamp t) const;
  /// The same with the IMU samples from f.t to t already preintegrated at f's biases.
  NavState predictWith(const WindowFrame& f, const Preintegration& pre, Timestamp t) const;
  void decideKeyframe(WindowFrame& f, int tracked);
  /// Zero-velocity update test for the newest frame: both frames' estimated speeds below zero_velocity.max_speed,
  /// the IMU at rest over zero_velocity.window_s and the points tracked from the previous frame still (median
  /// motion below zero_velocity.max_motion_px).
  bool detectRest(const WindowFrame& prev, const WindowFrame& f) const;
  bool failureAfterSolve(const NavState& predicted) const;
  void resetAfterFailure(const FrameObservations& obs, const NavState& state, EstimatorOutput* out);
  EstimatorOutput output(const WindowFrame& f) const;

  // --- estimator_solve.cc
  void repropagateIfNeeded();
  std::vector<ResidualSpec> imuResiduals(int first, int last);
  /// Rest priors of the frames first..last detected at rest: zero velocity, and no motion from the window frame
  /// before (when there is one).
  std::vector<ResidualSpec> zeroVelocityResiduals(int first, int last);
  /// all_right: every cam1 residual (the initialisation's solve), else as solver.right_residuals_all_frames says.
  void solveWindow(int max_iterations, bool all_right = false);
  /// True for the per-frame solve of a frame that is not a keyframe (solver.calibration_on_keyframes and
  /// solver.lines_on_keyframes hold blocks in it).
  bool nonKeyframeSolve(bool all_right) const;
  void solveWindowSchurLm(int max_iterations, bool all_right);
  /// Per-frame cost weights of the patent's point / line weighting (empty when lines.weighting is off).
  std::map<FrameId, double> frameWeights(bool for_lines) const;
  /// The robust loss of a residual spec (point or line Huber), nullptr if not robust.
  ceres::LossFunction* lossOf(const ResidualSpec& r);
  /// Observes the frame's lines (when lines are enabled).
  void observeLines(FrameId frame, const FrameObservations& obs);
  /// Removes the window's landmarks (points dropped, good lines kept in the map).
  void clearLandmarks();
  void slideWindow();
  void marginaliseOldest();
  void dropFrame(int index);
  /// After an IMU gap too long to bridge: drop the window and restart from the last good pose (propagated at
  /// constant velocity over the gap), counted as a re-initialisation.
  void restartAfterImuGap(Timestamp t);

  // --- estimator_calibration.cc (online extrinsics and time offset, options_.extrinsics / time_offset)
  /// The current rig correction T_B_R (identity unless extrinsics.estimate).
  Pose rigCorrection() const;
  /// cam0's extrinsics as the estimator currently believes them (the calibration's, corrected).
  Pose T_B_C0() const { return rigCorrection() * T_B_C0_; }
  /// The current stereo correction S of cam1 (identity unless estimated).
  Pose stereoCorrection() const { return rig_held_ ? stereo_applied_ : poseFromBlock(stereo_.data()); }
  /// cam1's extrinsics as the landmarks' residuals use them (the corrections of the last applyRig); needs T_B_C1_.
  Pose appliedT_B_C1() const { return rig_applied_ * *T_B_C1_ * stereo_applied_; }
  /// Whether cam1's correction S is a block of the window now.
  bool stereoEstimated() const {
    return options_.extrinsics.estimate && options_.extrinsics.estimate_stereo && T_B_C1_.has_value();
  }
  /// Wraps the visual residuals that involve body poses in RigCorrectedFactor and TimeShiftedFactor (each when
  /// estimated).
  void correctCalibration(std::vector<ResidualSpec>* residuals);
  /// Holds t_d and the rig correction once their estimate_for_s of tracked time in motion has passed (called
  /// before each window solve).
  void updateCalibrationHolds();
  /// Sets every window frame's capture_shift for the held t_d (identity while t_d is estimated or not used): a
  /// held offset costs nothing in the solve, unlike the TimeShiftedFactor wrapper.
  void setCaptureShifts();
  /// Every window frame's capture_shift for a time offset td, s.
  void setCaptureShifts(double td);
  /// The camera-to-IMU time offset in use, s.
  double timeOffset() const { return time_offset_held_ ? time_offset_held_value_ : time_offset_[0]; }
  /// Hands the current rig correction to the landmarks (after a solve): residuals built from now on contain it.
  void applyRig();
  /// The priors on the rig correction and the time offset at their current values (those estimated): start a window.
  void addCalibrationPriors();
  /// Measured angular rate at t: mean of the gyroscope over the 10 ms before t (zero if the IMU does not cover it).
  Vec3 gyroAt(Timestamp t) const;
  /// Data block, ambient size and manifold of a frame, rig or time-offset key.
  double* blockOf(BlockKey key);
  int ambientSizeOf(BlockKey key) const;
  const ceres::Manifold* manifoldOf(BlockKey key) const;

  EstimatorOptions options_;
  ImuNoise noise_;
  Pose T_B_C0_;                    // the calibration's extrinsics
  std::optional<Pose> T_B_C1_;
  std::array<double, 7> rig_{0, 0, 0, 0, 0, 0, 1};  // rig correction T_B_R block (PoseManifold), see pose_wrappers.h
  Pose rig_applied_;               // the correction the landmarks' extrinsics contain
  std::array<double, 7> stereo_{0, 0, 0, 0, 0, 0, 1};  // cam1's correction S (PoseManifold), held with the rig
  Pose stereo_applied_;            // the S the landmarks' cam1 extrinsics contain
  std::array<double, 1> time_offset_{0.0};  // camera-to-IMU time offset t_d, s
  Timestamp calibration_last_t_ = -1;       // newest frame of the last solve with online calibration
  double calibration_moving_s_ = 0.0;       // tracked time in motion (frames not at rest) since then, s
  bool rig_held_ = false;                   // extrinsics.estimate_for_s has passed: the correction is rig_applied_
  bool time_offset_held_ = false;           // estimate_for_s has passed: t_d is held at time_offset_held_value_
  double time_offset_held_value_ = 0.0;
  Vec3 g_W_;

  PreintegrationOptions preint_options_;  // with the gap noise of options_.imu_gap
  ImuBuffer imu_;
  Timestamp imu_gap_start_ = -1;        // start of a gap longer than imu_gap.max_bridge_s, until the next frame
  Timestamp imu_gap_end_ = -1;
  Window window_;
  PointLandmarks points_;
  LineLandmarks lines_;
  std::vector<std::shared_ptr<const MarginalizationPrior>> priors_;
  PoseManifold pose_manifold_;
  LineManifold line_manifold_;
  ceres::HuberLoss huber_;
  std::unique_ptr<ceres::LossFunction> line_loss_;  // lines.loss at lines.huber_px

  // Per-frame timing of the line-only steps and of the solve, ms (reset by addFrame).
  double line_ms_ = 0.0;
  double solver_ms_ = 0.0;

  Mode mode_ = Mode::kWaitingForFirstFrame;
  std::optional<NavState> last_good_;   // newest state of the last good solve (for re-initialisation)
  Timestamp last_frame_t_ = 0;
  bool have_frame_ = false;
  int reinitialisations_ = 0;
  Timestamp lost_since_ = -1;           // first frame time of the current failure, -1 if tracking
};

}  // namespace linnet
