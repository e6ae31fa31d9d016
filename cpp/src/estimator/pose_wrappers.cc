#include "linnet/estimator/factors/pose_wrappers.h"

#include <array>

#include "linnet/core/error.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

namespace {
using RowMat = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
}  // namespace

PoseWrappedFactor::PoseWrappedFactor(std::shared_ptr<ceres::CostFunction> inner, std::vector<int> pose_blocks,
                                     int extra_size, bool extra_is_pose)
    : inner_(std::move(inner)),
      pose_blocks_(std::move(pose_blocks)),
      extra_tangent_(extra_is_pose ? kPoseTangentSize : extra_size),
      extra_is_pose_(extra_is_pose) {
  if (extra_is_pose && extra_size != kPoseAmbientSize) throw UsageError("PoseWrappedFactor: a pose block has 7 values");
  set_num_residuals(inner_->num_residuals());
  std::vector<int32_t>* sizes = mutable_parameter_block_sizes();
  *sizes = inner_->parameter_block_sizes();
  sizes->push_back(extra_size);
}

bool PoseWrappedFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const int n_inner = static_cast<int>(inner_->parameter_block_sizes().size());
  const int rows = num_residuals();
  const double* extra = parameters[n_inner];
  const std::size_t n_poses = pose_blocks_.size();

  // Inner parameters with the body poses replaced by the transformed poses.
  std::vector<std::array<double, kPoseAmbientSize>> moved(n_poses);
  std::vector<Mat6> d_body(n_poses);
  std::vector<Eigen::MatrixXd> d_extra(n_poses);
  std::vector<const double*> inner_params(parameters, parameters + n_inner);
  for (std::size_t k = 0; k < n_poses; ++k) {
    const Pose T = transform(k, poseFromBlock(parameters[pose_blocks_[k]]), extra, &d_body[k], &d_extra[k]);
    setPose(T, moved[k].data());
    inner_params[static_cast<std::size_t>(pose_blocks_[k])] = moved[k].data();
  }
  if (jacobians == nullptr) return inner_->Evaluate(inner_params.data(), residuals, nullptr);

  const bool want_extra = jacobians[n_inner] != nullptr;
  // Inner Jacobians: straight into the output for the other blocks, into scratch for the poses.
  std::vector<RowMat> pose_scratch(n_poses, RowMat(rows, kPoseAmbientSize));
  std::vector<double*> inner_jac(jacobians, jacobians + n_inner);
  for (std::size_t k = 0; k < n_poses; ++k) {
    const auto b = static_cast<std::size_t>(pose_blocks_[k]);
    if (jacobians[b] != nullptr || want_extra) inner_jac[b] = pose_scratch[k].data();
  }
  if (!inner_->Evaluate(inner_params.data(), residuals, inner_jac.data())) return false;

  Eigen::MatrixXd J_extra = Eigen::MatrixXd::Zero(rows, extra_tangent_);
  for (std::size_t k = 0; k < n_poses; ++k) {
    const int b = pose_blocks_[k];
    if (jacobians[b] == nullptr && !want_extra) continue;
    // Tangent Jacobian w.r.t. the transformed pose: ambient times PoseManifold's PlusJacobian there.
    Eigen::MatrixXd J_t(rows, kPoseTangentSize);
    J_t.leftCols(3) = pose_scratch[k].leftCols(3);
    J_t.rightCols(3) = pose_scratch[k].rightCols(4) * quatPlusJacobian(poseRotation(moved[k].data()));
    if (jacobians[b] != nullptr) {
      const Eigen::MatrixXd J_body = J_t * d_body[k];
      tangentToAmbientPose<Eigen::Dynamic>(J_body, parameters[b], jacobians[b]);
    }
    if (want_extra) J_extra += J_t * d_extra[k];
  }
  if (want_extra) {
    if (extra_is_pose_) {
      tangentToAmbientPose<Eigen::Dynamic>(J_extra, extra, jacobians[n_inner]);
    } else {
      Eigen::Map<RowMat>(jacobians[n_inner], rows, extra_tangent_) = J_extra;
    }
  }
  return true;
}

RigCorrectedFactor::RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::vector<int> pose_blocks,
                                       const Pose& T_B_R0)
    : PoseWrappedFactor(std::move(inner), std::move(pose_blocks), kPoseAmbientSize, true), D_(T_B_R0.inverse()) {}

Pose RigCorrectedFactor::transform(std::size_t /*k*/, const Pose& body, const double* extra, Mat6* d_body,
                                   Eigen::MatrixXd* d_extra) const {
  const Pose T_B_R = poseFromBlock(extra);
  const Pose M = T_B_R * D_;
  const Mat3 R_B = body.R();
  d_body->setIdentity();
  d_body->topRightCorner<3, 3>() = -R_B * skew(M.p);
  d_body->bottomRightCorner<3, 3>() = M.R().transpose();
  d_extra->setZero(6, 6);
  d_extra->topLeftCorner(3, 3) = R_B;
  d_extra->topRightCorner(3, 3) = -R_B * T_B_R.R() * skew(D_.p);
  d_extra->bottomRightCorner(3, 3) = D_.R().transpose();
  return body * M;
}

TimeShiftedFactor::TimeShiftedFactor(std::shared_ptr<ceres::CostFunction> inner, std::vector<int> pose_blocks,
                                     std::vector<Vec3> v_W, std::vector<Vec3> w_B)
    : PoseWrappedFactor(std::move(inner), std::move(pose_blocks), 1, false),
      v_W_(std::move(v_W)),
      w_B_(std::move(w_B)) {}

Pose TimeShiftedFactor::transform(std::size_t k, const Pose& body, const double* extra, Mat6* d_body,
                                  Eigen::MatrixXd* d_extra) const {
  const double td = extra[0];
  const Quat E = expSO3(-td * w_B_[k]);
  d_body->setIdentity();
  d_body->bottomRightCorner<3, 3>() = E.toRotationMatrix().transpose();
  d_extra->resize(6, 1);
  d_extra->topRows(3) = -v_W_[k];
  d_extra->bottomRows(3) = -w_B_[k];
  return Pose(body.q * E, body.p - td * v_W_[k]);
}

}  // namespace linnet
