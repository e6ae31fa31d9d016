// Rigid transforms and SO(3) helpers.
//
// Convention (../shared/DESIGN.md A3): T_A_B maps coordinates in B to A, p_A = T_A_B * p_B.
// Rotations are Hamilton quaternions; perturbations are on the right: R <- R * Exp(dtheta).
#pragma once

#include <cmath>

#include "linnet/core/types.h"

namespace linnet {

/// Rigid transform T_A_B = (q_A_B, p_A) where p_A is the origin of B expressed in A.
struct Pose {
  Quat q = Quat::Identity();
  Vec3 p = Vec3::Zero();

  Pose() = default;
  Pose(const Quat& q_in, const Vec3& p_in) : q(q_in.normalized()), p(p_in) {}
  Pose(const Mat3& R, const Vec3& p_in) : q(Quat(R).normalized()), p(p_in) {}

  static Pose identity() { return Pose(); }
  /// From a 4x4 homogeneous matrix (the rotation block is re-orthonormalised through the quaternion).
  static Pose fromMatrix(const Mat4& T) { return Pose(Mat3(T.block<3, 3>(0, 0)), Vec3(T.block<3, 1>(0, 3))); }

  Mat3 R() const { return q.toRotationMatrix(); }
  Mat4 matrix() const {
    Mat4 T = Mat4::Identity();
    T.block<3, 3>(0, 0) = R();
    T.block<3, 1>(0, 3) = p;
    return T;
  }
  Pose inverse() const {
    const Quat qi = q.conjugate();
    return Pose(qi, -(qi * p));
  }
  Pose operator*(const Pose& o) const { return Pose(q * o.q, p + q * o.p); }
  Vec3 operator*(const Vec3& x) const { return q * x + p; }
};

/// Skew-symmetric matrix [v]x with [v]x w = v x w.
inline Mat3 skew(const Vec3& v) {
  Mat3 S;
  S << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return S;
}

/// SO(3) exponential as a unit quaternion.
inline Quat expSO3(const Vec3& w) {
  const double theta = w.norm();
  if (theta < 1e-10) {
    Quat q(1.0, 0.5 * w.x(), 0.5 * w.y(), 0.5 * w.z());
    return q.normalized();
  }
  const Vec3 axis = w / theta;
  return Quat(Eigen::AngleAxisd(theta, axis));
}

/// SO(3) logarithm of a unit quaternion (rotation vector, angle in [0, pi]).
inline Vec3 logSO3(const Quat& q_in) {
  Quat q = q_in.normalized();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const double sin_half = q.vec().norm();
  if (sin_half < 1e-10) return 2.0 * q.vec();
  const double theta = 2.0 * std::atan2(sin_half, q.w());
  return q.vec() * (theta / sin_half);
}

/// Right Jacobian of SO(3): Exp(w + dw) ~= Exp(w) Exp(Jr(w) dw).
inline Mat3 rightJacobianSO3(const Vec3& w) {
  const double theta = w.norm();
  const Mat3 W = skew(w);
  if (theta < 1e-6) return Mat3::Identity() - 0.5 * W + W * W / 6.0;
  const double t2 = theta * theta;
  return Mat3::Identity() - (1.0 - std::cos(theta)) / t2 * W + (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

/// Inverse of the right Jacobian of SO(3).
inline Mat3 rightJacobianInvSO3(const Vec3& w) {
  const double theta = w.norm();
  const Mat3 W = skew(w);
  if (theta < 1e-6) return Mat3::Identity() + 0.5 * W + W * W / 12.0;
  const double t2 = theta * theta;
  return Mat3::Identity() + 0.5 * W +
         (1.0 / t2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta))) * W * W;
}

/// Left and right quaternion-multiplication matrices on coefficient vectors ordered (w, x, y, z):
/// q * p = quatLeft(q) [p.w p.x p.y p.z]^T = quatRight(p) [q.w q.x q.y q.z]^T.
inline Mat4 quatLeft(const Quat& q) {
  Mat4 m;
  m(0, 0) = q.w();
  m.block<1, 3>(0, 1) = -q.vec().transpose();
  m.block<3, 1>(1, 0) = q.vec();
  m.block<3, 3>(1, 1) = q.w() * Mat3::Identity() + skew(q.vec());
  return m;
}
inline Mat4 quatRight(const Quat& p) {
  Mat4 m;
  m(0, 0) = p.w();
  m.block<1, 3>(0, 1) = -p.vec().transpose();
  m.block<3, 1>(1, 0) = p.vec();
  m.block<3, 3>(1, 1) = p.w() * Mat3::Identity() - skew(p.vec());
  return m;
}

}  // namespace linnet
