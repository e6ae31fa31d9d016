#include "linnet/estimator/factors/zero_velocity_factor.h"

#include "linnet/core/pose.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

bool ZeroVelocityFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  for (int k = 0; k < 3; ++k) residuals[k] = inv_sigma_ * parameters[0][k];
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 9; ++c) jacobians[0][r * 9 + c] = r == c ? inv_sigma_ : 0.0;
  }
  return true;
}

bool NoMotionFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const Pose Ti = poseFromBlock(parameters[0]), Tj = poseFromBlock(parameters[1]);
  const Quat q_ij = Ti.q.conjugate() * Tj.q;
  const Vec3 theta = logSO3(q_ij);
  Eigen::Map<Eigen::Matrix<double, 6, 1>> r(residuals);
  r.head<3>() = inv_p_ * (Tj.p - Ti.p);
  r.tail<3>() = inv_r_ * theta;
  if (jacobians == nullptr) return r.allFinite();
  const Mat3 Jinv = rightJacobianInvSO3(theta);
  for (int b = 0; b < 2; ++b) {
    if (jacobians[b] == nullptr) continue;
    Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Zero();
    J.topLeftCorner<3, 3>() = (b == 0 ? -inv_p_ : inv_p_) * Mat3::Identity();
    J.bottomRightCorner<3, 3>() = b == 0 ? Mat3(-inv_r_ * Jinv * q_ij.toRotationMatrix().transpose())
                                         : Mat3(inv_r_ * Jinv);
    tangentToAmbientPose<6>(J, parameters[b], jacobians[b]);
  }
  return r.allFinite();
}

}  // namespace linnet
