// PoseManifold: R^3 x SO(3) with the position perturbed in W and the rotation perturbed on the right.
#include "linnet/estimator/manifolds.h"

namespace linnet {

bool PoseManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Vec3> p(x);
  const Eigen::Map<const Quat> q(x + 3);
  const Eigen::Map<const Vec3> dp(delta);
  const Eigen::Map<const Vec3> dtheta(delta + 3);
  Eigen::Map<Vec3> p_out(x_plus_delta);
  Eigen::Map<Quat> q_out(x_plus_delta + 3);
  p_out = p + dp;
  q_out = (q * expSO3(dtheta)).normalized();
  return true;
}

bool PoseManifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 7, 6, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.topLeftCorner<3, 3>().setIdentity();
  J.bottomRightCorner<4, 3>() = quatPlusJacobian(Eigen::Map<const Quat>(x + 3));
  return true;
}

bool PoseManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const Eigen::Map<const Quat> qx(x + 3);
  const Eigen::Map<const Quat> qy(y + 3);
  Eigen::Map<Vec3> dp_out(y_minus_x);
  Eigen::Map<Vec3> dtheta_out(y_minus_x + 3);
  dp_out = Eigen::Map<const Vec3>(y) - Eigen::Map<const Vec3>(x);
  dtheta_out = logSO3(qx.conjugate() * qy);
  return true;
}

bool PoseManifold::MinusJacobian(const double* x, double* jacobian) const {
  // Near y = x, Log(qx^-1 qy) ~= 2 vec(qx^-1 qy) = 2 (qx.w qy.vec - qy.w qx.vec - qx.vec x qy.vec),
  // which is 4 L(qx)^T applied to qy's coefficients (L = quatPlusJacobian).
  Eigen::Map<Eigen::Matrix<double, 6, 7, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.topLeftCorner<3, 3>().setIdentity();
  J.bottomRightCorner<3, 4>() = 4.0 * quatPlusJacobian(Eigen::Map<const Quat>(x + 3)).transpose();
  return true;
}

}  // namespace linnet
