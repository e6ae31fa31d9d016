// PoseManifold: R^3 x SO(3) with the position perturbed in W and the rotation perturbed on the right.
#include "linnet/estimator/manifolds.h"

#include <cmath>

#include "linnet/geometry/plucker.h"

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

// ---------------------------------------------------------------------------------------------------------------
// LineManifold: Plücker block, orthonormal update.

namespace {

Eigen::Matrix<double, 6, 4> linePlusJacobian(const OrthonormalLine& o) {
  const Vec3 u1 = o.U.col(0), u2 = o.U.col(1), u3 = o.U.col(2);
  const double w1 = o.w.x(), w2 = o.w.y();
  // d(w1 u1, w2 u2) with dU = U [dpsi]x (du_i = -U [e_i]x dpsi) and dW = W R(dphi) (dw1 = -w2 dphi, dw2 = w1 dphi).
  Eigen::Matrix<double, 6, 4> J;
  J.block<3, 1>(0, 0).setZero();
  J.block<3, 1>(0, 1) = -w1 * u3;
  J.block<3, 1>(0, 2) = w1 * u2;
  J.block<3, 1>(0, 3) = -w2 * u1;
  J.block<3, 1>(3, 0) = w2 * u3;
  J.block<3, 1>(3, 1).setZero();
  J.block<3, 1>(3, 2) = -w2 * u1;
  J.block<3, 1>(3, 3) = w1 * u2;
  return J;
}

}  // namespace

bool LineManifold::Plus(const double* x, const double* delta, double* x_plus_delta) const {
  const Eigen::Map<const Vec6> L(x);
  OrthonormalLine o = toOrthonormal(L);
  const Eigen::Map<const Vec3> dpsi(delta);
  o.U = o.U * expSO3(dpsi).toRotationMatrix();
  const double phi = std::atan2(o.w.y(), o.w.x()) + delta[3];
  o.w = Vec2(std::cos(phi), std::sin(phi));
  Eigen::Map<Vec6> out(x_plus_delta);
  out = fromOrthonormal(o);
  return true;
}

bool LineManifold::PlusJacobian(const double* x, double* jacobian) const {
  Eigen::Map<Eigen::Matrix<double, 6, 4, Eigen::RowMajor>> J(jacobian);
  J = linePlusJacobian(toOrthonormal(Eigen::Map<const Vec6>(x)));
  return true;
}

bool LineManifold::Minus(const double* y, const double* x, double* y_minus_x) const {
  const OrthonormalLine ox = toOrthonormal(Eigen::Map<const Vec6>(x));
  const OrthonormalLine oy = toOrthonormal(Eigen::Map<const Vec6>(y));
  Eigen::Map<Vec3> dpsi(y_minus_x);
  dpsi = logSO3(Quat(Mat3(ox.U.transpose() * oy.U)));
  double dphi = std::atan2(oy.w.y(), oy.w.x()) - std::atan2(ox.w.y(), ox.w.x());
  dphi = std::remainder(dphi, 2.0 * M_PI);
  y_minus_x[3] = dphi;
  return true;
}

bool LineManifold::MinusJacobian(const double* x, double* jacobian) const {
  // Exact derivative of Minus(y, x) at y = x in every ambient direction (Minus orthogonalises n against v first):
  //   u2 = v/|v|: dpsi1 = u3 . dv / |v|, dpsi3 = -u1 . dv / |v|;  u1 = n/|n|: dpsi2 = -u3 . dn / |n|;
  //   phi = atan2(|v|, |n|): dphi = (|n| u2 . dv - |v| u1 . dn) / (|n|^2 + |v|^2).
  // On the tangent space it is the pseudo-inverse of PlusJacobian.
  const Eigen::Map<const Vec6> L(x);
  const OrthonormalLine o = toOrthonormal(L);
  const Vec3 u1 = o.U.col(0), u2 = o.U.col(1), u3 = o.U.col(2);
  const double v_norm = L.tail<3>().norm();
  const double n_norm = (L.head<3>() - L.head<3>().dot(u2) * u2).norm();
  const double s2 = n_norm * n_norm + v_norm * v_norm;
  Eigen::Map<Eigen::Matrix<double, 4, 6, Eigen::RowMajor>> J(jacobian);
  J.setZero();
  J.block<1, 3>(0, 3) = u3.transpose() / v_norm;
  if (n_norm > 0.0) J.block<1, 3>(1, 0) = -u3.transpose() / n_norm;
  J.block<1, 3>(2, 3) = -u1.transpose() / v_norm;
  J.block<1, 3>(3, 0) = -v_norm / s2 * u1.transpose();
  J.block<1, 3>(3, 3) = n_norm / s2 * u2.transpose();
  return true;
}

}  // namespace linnet
