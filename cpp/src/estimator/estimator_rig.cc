// Online refinement of the camera-IMU extrinsics: one correction T_B_R of the stereo rig, common to both cameras,
// in the window like a frame block (factors/rig_factor.h). It enters each window with a prior at its current value
// (sigmas in options_.extrinsics) and is never marginalised, so what the window learnt about it stays in the priors.
#include <algorithm>

#include "estimator_core.h"
#include "linnet/estimator/factors/rig_factor.h"

namespace linnet {

Pose EstimatorCore::rigCorrection() const { return poseFromBlock(rig_.data()); }

void EstimatorCore::correctRig(std::vector<ResidualSpec>* residuals) const {
  if (!options_.extrinsics.estimate) return;
  for (ResidualSpec& r : *residuals) {
    std::vector<int> poses;
    for (std::size_t b = 0; b < r.keys.size(); ++b)
      if (r.keys[b] >= 0) poses.push_back(static_cast<int>(b));  // visual residuals: frame keys are pose blocks
    if (poses.empty()) continue;  // the same-frame stereo residual does not depend on a common correction
    r.cost = std::make_shared<RigCorrectedFactor>(r.cost, std::move(poses), rig_applied_);
    r.blocks.push_back(const_cast<double*>(rig_.data()));
    r.keys.push_back(kRigBlockKey);
  }
}

void EstimatorCore::applyRig() {
  if (!options_.extrinsics.estimate) return;
  rig_applied_ = rigCorrection();
  std::optional<Pose> c1;
  if (T_B_C1_.has_value()) c1 = rig_applied_ * *T_B_C1_;
  points_.setExtrinsics(rig_applied_ * T_B_C0_, c1);
  lines_.setExtrinsics(rig_applied_ * T_B_C0_, c1);
}

void EstimatorCore::addRigPrior() {
  if (!options_.extrinsics.estimate) return;
  const ExtrinsicsOptions& o = options_.extrinsics;
  auto p = std::make_shared<MarginalizationPrior>();
  p->keys = {kRigBlockKey};
  p->ambient_sizes = {kPoseAmbientSize};
  p->tangent_sizes = {kPoseTangentSize};
  p->tangent_offsets = {0};
  p->x0 = {std::vector<double>(rig_.begin(), rig_.end())};
  p->manifolds = {&pose_manifold_};
  p->J = Eigen::MatrixXd::Zero(6, 6);
  p->J.topLeftCorner<3, 3>() = Mat3::Identity() / o.prior_translation_m;
  p->J.bottomRightCorner<3, 3>() = Mat3::Identity() / (o.prior_rotation_deg * M_PI / 180.0);
  p->r = Eigen::VectorXd::Zero(6);
  priors_.push_back(p);
}

double* EstimatorCore::blockOf(BlockKey key) { return key == kRigBlockKey ? rig_.data() : window_.block(key); }

int EstimatorCore::ambientSizeOf(BlockKey key) const {
  if (key == kRigBlockKey) return kPoseAmbientSize;
  return key % 4 == static_cast<int>(BlockKind::kPose) ? kPoseAmbientSize : kSpeedBiasSize;
}

const ceres::Manifold* EstimatorCore::manifoldOf(BlockKey key) const {
  return ambientSizeOf(key) == kPoseAmbientSize ? &pose_manifold_ : nullptr;
}

}  // namespace linnet
