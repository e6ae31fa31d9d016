// Parameter-block manifolds and block accessors shared by every estimator factor.
//
// Block layouts (a contract for all estimator code):
//   pose        double[7] = [px, py, pz, qx, qy, qz, qw]   T_W_B, quaternion in Eigen coeffs order (Hamilton)
//   speed-bias  double[9] = [v_W (3), b_a (3), b_g (3)]     Euclidean
//   inverse depth double[1]                                  Euclidean
//   line        double[6] = [n (3), v (3)]                  Plücker coordinates in W, unit norm (LineManifold)
//
// PoseManifold: tangent [dp, dtheta] (6), Plus(x, d) = (p + dp, q * Exp(dtheta)) -- the position is perturbed
// in W, the rotation on the right (DESIGN A3). Minus(y, x) = (p_y - p_x, Log(q_x^-1 q_y)).
//
// Factors compute Jacobians in the tangent space (R x 6) and convert them with tangentToAmbientPose(), which
// returns an ambient (R x 7) Jacobian J_a with J_a * PlusJacobian(x) == J_tangent, so Ceres (which multiplies
// by the PlusJacobian) sees exactly the tangent Jacobian.
#pragma once

#include <ceres/manifold.h>

#include <Eigen/Core>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

inline constexpr int kPoseAmbientSize = 7;
inline constexpr int kPoseTangentSize = 6;
inline constexpr int kSpeedBiasSize = 9;
inline constexpr int kLineAmbientSize = 6;
inline constexpr int kLineTangentSize = 4;

/// SE(3)-like manifold R^3 x SO(3) for a pose block [p, q(xyzw)] with right rotation perturbation.
class PoseManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kPoseAmbientSize; }
  int TangentSize() const override { return kPoseTangentSize; }
  /// x_plus_delta = (p + dp, q * Exp(dtheta)); the result quaternion is re-normalised.
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  /// d Plus(x, delta) / d delta at delta = 0, 7 x 6, row-major.
  bool PlusJacobian(const double* x, double* jacobian) const override;
  /// y_minus_x = (p_y - p_x, Log(q_x^-1 q_y)).
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  /// d Minus(y, x) / d y at y = x, 6 x 7, row-major.
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// The 4-DoF manifold of 3D lines (DESIGN B1; Bartoli & Sturm 2005): the block holds the Plücker coordinates
/// L = [n; v] in W, the update is the orthonormal representation's: with (U, W) = toOrthonormal(L) (plucker.h),
/// Plus(L, [dpsi (3), dphi]) = fromOrthonormal(U Exp(dpsi), W R(dphi)), a unit-norm L. Minus(L2, L1) =
/// (Log(U1^T U2), phi2 - phi1). PlusJacobian = [[0, -w1 u3, w1 u2, -w2 u1], [w2 u3, 0, -w2 u1, w1 u2]] (6 x 4);
/// its columns are orthogonal with squared norms (w2^2, w1^2, 1, 1), so MinusJacobian is its pseudo-inverse.
/// Factors give Ceres the ambient Jacobian d r / d L directly (residuals are invariant to the scale of L).
class LineManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return kLineAmbientSize; }
  int TangentSize() const override { return kLineTangentSize; }
  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override;
  bool PlusJacobian(const double* x, double* jacobian) const override;
  bool Minus(const double* y, const double* x, double* y_minus_x) const override;
  bool MinusJacobian(const double* x, double* jacobian) const override;
};

/// A pose block: 7 values on PoseManifold, the blocks whose Jacobians a TangentJacobians factor gives in the tangent
/// space (factors/tangent_jacobians.h).
inline bool isPoseBlock(int ambient_size, const ceres::Manifold* manifold) {
  return ambient_size == kPoseAmbientSize && dynamic_cast<const PoseManifold*>(manifold) != nullptr;
}

/// Position of a pose block.
inline Eigen::Map<const Vec3> posePosition(const double* pose) { return Eigen::Map<const Vec3>(pose); }

/// Rotation of a pose block (copied, normalised).
inline Quat poseRotation(const double* pose) { return Eigen::Map<const Quat>(pose + 3).normalized(); }

/// Pose of a pose block.
inline Pose poseFromBlock(const double* pose) { return Pose(poseRotation(pose), Vec3(posePosition(pose))); }

/// Writes a pose into a 7-double block.
inline void setPose(const Pose& T, double* pose) {
  Eigen::Map<Vec3> p_out(pose);
  Eigen::Map<Quat> q_out(pose + 3);
  p_out = T.p;
  q_out = T.q.normalized();
}

/// 4 x 3 matrix L with q' coeffs ~= q coeffs + L dtheta for q' = q * Exp(dtheta), coeffs in (x, y, z, w)
/// order. It is the rotation part of PoseManifold's PlusJacobian.
inline Eigen::Matrix<double, 4, 3> quatPlusJacobian(const Quat& q) {
  // q * [1, d/2] = q + 0.5 * (q.w d + q.vec x d, -q.vec . d)
  Eigen::Matrix<double, 4, 3> L;
  L.topRows<3>() = 0.5 * (q.w() * Mat3::Identity() + skew(q.vec()));
  L.row(3) = -0.5 * q.vec().transpose();
  return L;
}

/// Ambient (R x 7, row-major) Jacobian from a tangent Jacobian (R x 6) w.r.t. [dp, dtheta] of the pose block
/// `pose`. J_ambient = [J_dp, 4 J_dtheta Lq^T]: since Lq^T Lq = I/4 for a unit q, J_ambient *
/// PlusJacobian(pose) equals J_tangent exactly. The component along q itself is zero (the residual is treated
/// as independent of |q|). R may be Eigen::Dynamic. (Row-major is what Ceres passes to
/// CostFunction::Evaluate.)
template <int R>
void tangentToAmbientPose(const Eigen::Matrix<double, R, 6>& J_tangent, const double* pose,
                          double* J_ambient_rowmajor) {
  using Ambient = Eigen::Matrix<double, R, 7, Eigen::RowMajor>;
  Eigen::Map<Ambient> J(J_ambient_rowmajor, J_tangent.rows(), 7);
  const Eigen::Matrix<double, 4, 3> L = quatPlusJacobian(poseRotation(pose));
  J.leftCols(3) = J_tangent.leftCols(3);
  J.rightCols(4) = 4.0 * J_tangent.rightCols(3) * L.transpose();
}

}  // namespace linnet
