// Online calibration in the window (factors/pose_wrappers.h): one correction T_B_R of the stereo rig's extrinsics,
// common to both cameras, cam1's correction S relative to cam0, and the camera-to-IMU time offset t_d. Each is a
// block of the window like a frame block:
// it enters each new window with a prior at its current value (sigmas in options_.extrinsics / time_offset) and is
// never marginalised, so what the window learns about it stays in the marginalisation priors.
#include <algorithm>
#include <array>
#include <span>

#include "estimator_core.h"
#include "linnet/estimator/factors/point_factors.h"
#include "linnet/estimator/factors/pose_wrappers.h"

namespace linnet {

Pose EstimatorCore::rigCorrection() const { return rig_held_ ? rig_applied_ : poseFromBlock(rig_.data()); }

Vec3 EstimatorCore::gyroAt(Timestamp t) const {
  const Timestamp t0 = t - fromSeconds(0.01);
  if (!imu_.covers(t0, t)) return Vec3::Zero();
  const std::vector<ImuSample> samples = imu_.samplesBetween(t0, t);
  Vec3 sum = Vec3::Zero();
  for (const ImuSample& s : samples) sum += s.gyr;
  return sum / static_cast<double>(samples.size());
}

void EstimatorCore::correctCalibration(std::vector<ResidualSpec>* residuals) {
  // A held t_d is in the frames' capture_shift (setCaptureShifts), a held correction in the landmarks' extrinsics.
  const bool rig = options_.extrinsics.estimate && !rig_held_;
  const bool time = options_.time_offset.estimate && !time_offset_held_;
  if (!rig && !time) return;
  const bool stereo = rig && stereoEstimated() && calibration_moving_s_ >= options_.extrinsics.stereo_from_s;
  const Pose T_B_C1 = stereo ? appliedT_B_C1() : Pose::identity();
  // One memo per kind of wrapper: the rig's constants are common to all residuals (tag 0), the stereo correction's,
  // the time shift's and the fused pair's are their frame's (tagged by frame).
  const auto rig_memo = std::make_shared<PoseTransformMemo>();
  const auto stereo_memo = std::make_shared<PoseTransformMemo>();
  const auto time_memo = std::make_shared<PoseTransformMemo>();
  const auto rig_time_memo = std::make_shared<PoseTransformMemo>();  // the fused wrapper's: tagged by frame
  const auto frameOf = [&](const ResidualSpec& r, int b) { return r.keys[static_cast<std::size_t>(b)] / 4; };
  for (ResidualSpec& r : *residuals) {
    // cam1's correction applies to cam1's pose on the body, so it is the innermost wrapper.
    if (stereo && r.cam1 == ResidualSpec::kCam1Pair) {
      r.cost = std::make_shared<PointStereoCorrectedFactor>(static_cast<const PointStereoFactor&>(*r.cost),
                                                            stereo_applied_);
      r.blocks.push_back(stereo_.data());
      r.keys.push_back(kStereoBlockKey);
    } else if (stereo && r.cam1 >= 0) {
      const WindowFrame* f = window_.find(frameOf(r, r.cam1));
      auto wrapped = RigCorrectedFactor::stereoCorrected(r.cost, r.cam1, f->capture_shift * T_B_C1, stereo_applied_);
      wrapped->useMemo(stereo_memo, {frameOf(r, r.cam1)});
      r.cost = std::move(wrapped);
      r.blocks.push_back(stereo_.data());
      r.keys.push_back(kStereoBlockKey);
    }
    // Visual residuals: their frame keys are pose blocks (one or two; fixed arrays, as this runs per residual).
    std::array<int, PoseWrappedFactor::kMaxPoses> poses{};
    std::array<std::int64_t, PoseWrappedFactor::kMaxPoses> frames{};
    std::size_t n_poses = 0;
    for (std::size_t b = 0; b < r.keys.size(); ++b) {
      if (r.keys[b] < 0 || r.keys[b] % 4 != static_cast<int>(BlockKind::kPose)) continue;
      if (n_poses == poses.size()) throw UsageError("correctCalibration: a visual residual with more than 2 poses");
      poses[n_poses] = static_cast<int>(b);
      frames[n_poses++] = frameOf(r, static_cast<int>(b));
    }
    if (n_poses == 0) continue;  // the same-frame stereo residual depends on neither
    const std::span<const int> pose_span(poses.data(), n_poses);
    const std::span<const std::int64_t> frame_span(frames.data(), n_poses);
    // The rig correction applies to the time-shifted body pose (the inner wrapper when nested). While both are
    // estimated, one wrapper composes them (same residual; the two maps applied once per pose, not level by level).
    std::array<Vec3, PoseWrappedFactor::kMaxPoses> v, w;
    if (time) {
      for (std::size_t k = 0; k < n_poses; ++k) {
        const WindowFrame* f = window_.find(frames[k]);
        v[k] = f->v();
        w[k] = f->gyr - f->bg();
      }
    }
    const std::span<const Vec3> v_span(v.data(), n_poses), w_span(w.data(), n_poses);
    if (rig && time) {
      auto wrapped = std::make_shared<RigTimeShiftedFactor>(r.cost, pose_span, rig_applied_, v_span, w_span);
      wrapped->useMemo(rig_time_memo, frame_span);
      r.cost = std::move(wrapped);
      r.blocks.push_back(rig_.data());
      r.keys.push_back(kRigBlockKey);
      r.blocks.push_back(time_offset_.data());
      r.keys.push_back(kTimeOffsetBlockKey);
      continue;
    }
    if (rig) {
      auto wrapped = std::make_shared<RigCorrectedFactor>(r.cost, pose_span, rig_applied_);
      const std::array<std::int64_t, PoseWrappedFactor::kMaxPoses> common{};  // the rig's constants: tag 0
      wrapped->useMemo(rig_memo, std::span<const std::int64_t>(common.data(), n_poses));
      r.cost = std::move(wrapped);
      r.blocks.push_back(rig_.data());
      r.keys.push_back(kRigBlockKey);
    }
    if (time) {
      auto wrapped = std::make_shared<TimeShiftedFactor>(r.cost, pose_span, v_span, w_span);
      wrapped->useMemo(time_memo, frame_span);
      r.cost = std::move(wrapped);
      r.blocks.push_back(time_offset_.data());
      r.keys.push_back(kTimeOffsetBlockKey);
    }
  }
}

void EstimatorCore::updateCalibrationHolds() {
  const bool td = options_.time_offset.estimate && !time_offset_held_;
  const bool rig = options_.extrinsics.estimate && !rig_held_;
  if ((!td && !rig) || window_.empty()) return;
  // Only time in motion counts: at rest neither the offset nor the extrinsics are observable.
  const WindowFrame& newest = window_.newest();
  if (calibration_last_t_ >= 0 && newest.t > calibration_last_t_ && !newest.at_rest)
    calibration_moving_s_ += toSeconds(newest.t - calibration_last_t_);
  calibration_last_t_ = newest.t;
  const double tracked_s = calibration_moving_s_;
  const double td_for = options_.time_offset.estimate_for_s, rig_for = options_.extrinsics.estimate_for_s;
  if (td && td_for > 0.0 && tracked_s > td_for) {
    time_offset_held_ = true;
    time_offset_held_value_ = time_offset_[0];
  }
  // The landmarks' extrinsics already hold the last solve's correction (applyRig); from now on they stay.
  if (rig && rig_for > 0.0 && tracked_s > rig_for) rig_held_ = true;
}

void EstimatorCore::setCaptureShifts() {
  if (!time_offset_held_) return;
  setCaptureShifts(time_offset_held_value_);
}

void EstimatorCore::setCaptureShifts(double td) {
  // The body at t - t_d to first order, as TimeShiftedFactor: (p - t_d v, R Exp(-t_d w)), written on the body side
  // with the rotation at this linearisation: T_W_B * (Exp(-t_d w), R^T (-t_d v)).
  for (int k = 0; k < window_.size(); ++k) {
    WindowFrame& f = window_[k];
    f.capture_shift = Pose(expSO3(-td * (f.gyr - f.bg())), f.T_W_B().R().transpose() * (-td * f.v()));
  }
}

void EstimatorCore::applyRig() {
  if (!options_.extrinsics.estimate || rig_held_) return;
  rig_applied_ = rigCorrection();
  if (stereoEstimated()) stereo_applied_ = stereoCorrection();
  std::optional<Pose> c1;
  if (T_B_C1_.has_value()) c1 = appliedT_B_C1();
  points_.setExtrinsics(rig_applied_ * T_B_C0_, c1);
  lines_.setExtrinsics(rig_applied_ * T_B_C0_, c1);
}

namespace {
/// A prior on one block at its current value `x` (ambient values), with square-root information `sqrt_info`
/// (tangent x tangent).
std::shared_ptr<const MarginalizationPrior> blockPrior(BlockKey key, const double* x, int ambient,
                                                       const ceres::Manifold* manifold, const Eigen::MatrixXd& sqrt_info) {
  auto p = std::make_shared<MarginalizationPrior>();
  p->keys = {key};
  p->ambient_sizes = {ambient};
  p->tangent_sizes = {static_cast<int>(sqrt_info.cols())};
  p->tangent_offsets = {0};
  p->x0 = {std::vector<double>(x, x + ambient)};
  p->manifolds = {manifold};
  p->J = sqrt_info;
  p->r = Eigen::VectorXd::Zero(sqrt_info.rows());
  return p;
}
}  // namespace

void EstimatorCore::addCalibrationPriors() {
  if (options_.extrinsics.estimate) {
    const ExtrinsicsOptions& o = options_.extrinsics;
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, 6);
    J.topLeftCorner<3, 3>() = Mat3::Identity() / o.prior_translation_m;
    J.bottomRightCorner<3, 3>() = Mat3::Identity() / (o.prior_rotation_deg * M_PI / 180.0);
    priors_.push_back(blockPrior(kRigBlockKey, rig_.data(), kPoseAmbientSize, &pose_manifold_, J));
  }
  if (stereoEstimated()) {
    const ExtrinsicsOptions& o = options_.extrinsics;
    Eigen::MatrixXd J = Eigen::MatrixXd::Zero(6, 6);
    J.topLeftCorner<3, 3>() = Mat3::Identity() / o.prior_stereo_translation_m;
    J.bottomRightCorner<3, 3>() = Mat3::Identity() / (o.prior_stereo_rotation_deg * M_PI / 180.0);
    priors_.push_back(blockPrior(kStereoBlockKey, stereo_.data(), kPoseAmbientSize, &pose_manifold_, J));
  }
  if (options_.time_offset.estimate) {
    const Eigen::MatrixXd J = Eigen::MatrixXd::Constant(1, 1, 1.0 / (1e-3 * options_.time_offset.prior_ms));
    priors_.push_back(blockPrior(kTimeOffsetBlockKey, time_offset_.data(), 1, nullptr, J));
  }
}

double* EstimatorCore::blockOf(BlockKey key) {
  if (key == kRigBlockKey) return rig_.data();
  if (key == kStereoBlockKey) return stereo_.data();
  if (key == kTimeOffsetBlockKey) return time_offset_.data();
  return window_.block(key);
}

int EstimatorCore::ambientSizeOf(BlockKey key) const {
  if (key == kRigBlockKey || key == kStereoBlockKey) return kPoseAmbientSize;
  if (key == kTimeOffsetBlockKey) return 1;
  return key % 4 == static_cast<int>(BlockKind::kPose) ? kPoseAmbientSize : kSpeedBiasSize;
}

const ceres::Manifold* EstimatorCore::manifoldOf(BlockKey key) const {
  return ambientSizeOf(key) == kPoseAmbientSize ? &pose_manifold_ : nullptr;
}

}  // namespace linnet
