#include "linnet/estimator/factors/rig_factor.h"

#include <algorithm>
#include <array>

#include "linnet/estimator/manifolds.h"

namespace linnet {

namespace {

using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

}  // namespace

RigCorrectedFactor::RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::vector<int> pose_blocks,
                                       const Pose& T_B_R0)
    : inner_(std::move(inner)), pose_blocks_(std::move(pose_blocks)), D_(T_B_R0.inverse()) {
  set_num_residuals(inner_->num_residuals());
  std::vector<int32_t>* sizes = mutable_parameter_block_sizes();
  *sizes = inner_->parameter_block_sizes();
  sizes->push_back(kPoseAmbientSize);
}

bool RigCorrectedFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const std::vector<int32_t>& inner_sizes = inner_->parameter_block_sizes();
  const int n_inner = static_cast<int>(inner_sizes.size());
  const int rows = num_residuals();
  const double* rig_block = parameters[n_inner];
  const Pose T_B_R = poseFromBlock(rig_block);
  const Pose M = T_B_R * D_;

  // Inner parameters with the body poses replaced by rig poses.
  std::vector<std::array<double, kPoseAmbientSize>> rig_poses(pose_blocks_.size());
  std::vector<const double*> inner_params(parameters, parameters + n_inner);
  std::vector<Pose> bodies(pose_blocks_.size());
  for (std::size_t k = 0; k < pose_blocks_.size(); ++k) {
    bodies[k] = poseFromBlock(parameters[pose_blocks_[k]]);
    setPose(bodies[k] * M, rig_poses[k].data());
    inner_params[static_cast<std::size_t>(pose_blocks_[k])] = rig_poses[k].data();
  }
  if (jacobians == nullptr) return inner_->Evaluate(inner_params.data(), residuals, nullptr);

  const bool want_rig = jacobians[n_inner] != nullptr;
  // Inner Jacobians: straight into the output for non-pose blocks, into scratch for the poses (needed for the rig).
  std::vector<RowMat> pose_scratch(pose_blocks_.size(), RowMat(rows, kPoseAmbientSize));
  std::vector<double*> inner_jac(jacobians, jacobians + n_inner);
  for (std::size_t k = 0; k < pose_blocks_.size(); ++k) {
    const int b = pose_blocks_[k];
    if (jacobians[b] != nullptr || want_rig) inner_jac[static_cast<std::size_t>(b)] = pose_scratch[k].data();
  }
  if (!inner_->Evaluate(inner_params.data(), residuals, inner_jac.data())) return false;

  Eigen::MatrixXd J_rig_tangent = Eigen::MatrixXd::Zero(rows, kPoseTangentSize);
  const Mat3 R_M_T = M.R().transpose();
  const Mat3 R_D_T = D_.R().transpose();
  const Mat3 R_BR = T_B_R.R();
  for (std::size_t k = 0; k < pose_blocks_.size(); ++k) {
    const int b = pose_blocks_[k];
    if (jacobians[b] == nullptr && !want_rig) continue;
    // Tangent Jacobian w.r.t. the rig pose (ambient times PoseManifold's PlusJacobian at the rig pose).
    const Eigen::Matrix<double, 4, 3> L = quatPlusJacobian(poseRotation(rig_poses[k].data()));
    Eigen::MatrixXd J_t(rows, kPoseTangentSize);
    J_t.leftCols(3) = pose_scratch[k].leftCols(3);
    J_t.rightCols(3) = pose_scratch[k].rightCols(4) * L;
    const Mat3 R_B = bodies[k].R();
    if (jacobians[b] != nullptr) {
      Eigen::MatrixXd J_body(rows, kPoseTangentSize);
      J_body.leftCols(3) = J_t.leftCols(3);
      J_body.rightCols(3) = -J_t.leftCols(3) * R_B * skew(M.p) + J_t.rightCols(3) * R_M_T;
      tangentToAmbientPose<Eigen::Dynamic>(J_body, parameters[b], jacobians[b]);
    }
    if (want_rig) {
      J_rig_tangent.leftCols(3) += J_t.leftCols(3) * R_B;
      J_rig_tangent.rightCols(3) += -J_t.leftCols(3) * R_B * R_BR * skew(D_.p) + J_t.rightCols(3) * R_D_T;
    }
  }
  if (want_rig) tangentToAmbientPose<Eigen::Dynamic>(J_rig_tangent, rig_block, jacobians[n_inner]);
  return true;
}

}  // namespace linnet
