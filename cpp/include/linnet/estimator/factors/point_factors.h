// The three point residuals of DESIGN B1 (thesis ch. 4), in normalised image coordinates.
//
// A point is an inverse depth rho anchored at its first observation: host frame i, host camera C_h,
// normalised observation uv_h, so p_Ch = (uv_h, 1) / rho. Transferred into a target camera C_t of frame j:
//     p_Bi = T_B_Ch p_Ch,  p_W = T_W_Bi p_Bi,  p_Bj = T_W_Bj^-1 p_W,  p_Ct = T_B_Ct^-1 p_Bj
//     r = sqrt_info * (p_Ct.xy / p_Ct.z - uv_t)
// Kinds: (1) same camera, two frames (T_B_C0, T_B_C0); (2) left camera at frame i -> right camera at frame j
// (T_B_C0, T_B_C1); (3) left -> right in the same frame: PointStereoFactor, which depends only on rho.
//
// Parameter blocks: pose T_W_Bi (7 = [p, q xyzw], PoseManifold), pose T_W_Bj (7), inverse depth (1).
// Extrinsics are constants. Jacobians are analytic in the tangent space [dp, dtheta] (p <- p + dp, R <- R
// Exp(dtheta)): the Schur solver takes them as they are (TangentJacobians), Ceres through tangentToAmbientPose().
#pragma once

#include <ceres/sized_cost_function.h>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/estimator/factors/tangent_jacobians.h"

namespace linnet {

/// Square-root information of a point residual in normalised coordinates: focal / sigma (sigma in pixels).
inline double pointSqrtInformation(double focal_px, double sigma_px = 1.5) { return focal_px / sigma_px; }

/// Kinds (1) and (2): the host observation transferred into another frame's camera.
class PointReprojectionFactor : public ceres::SizedCostFunction<2, 7, 7, 1>, public TangentJacobians {
 public:
  PointReprojectionFactor(const Vec2& uv_host, const Vec2& uv_target, const Pose& T_B_Chost,
                          const Pose& T_B_Ctarget, double sqrt_info);
  /// As if constructed anew with these arguments (FactorPool).
  void reset(const Vec2& uv_host, const Vec2& uv_target, const Pose& T_B_Chost, const Pose& T_B_Ctarget,
             double sqrt_info);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;
  bool evaluateTangentSpace(double const* const* parameters, double* residuals, double** jacobians) const override;

  /// Residual and tangent Jacobians (w.r.t. [dp_i, dtheta_i], [dp_j, dtheta_j], rho); any output may be
  /// nullptr. Returns false if the result is not finite.
  bool evaluateTangent(const Pose& T_W_Bi, const Pose& T_W_Bj, double inv_depth, Vec2* residual,
                       Eigen::Matrix<double, 2, 6>* J_pose_i, Eigen::Matrix<double, 2, 6>* J_pose_j,
                       Vec2* J_inv_depth) const;

  const Vec2& uvHost() const { return uv_host_; }
  const Vec2& uvTarget() const { return uv_target_; }

 private:
  Vec2 uv_host_, uv_target_;
  Pose T_B_Ch_, T_B_Ct_;
  double sqrt_info_;
};

/// Kind (3): left -> right camera of the same frame; depends only on the inverse depth.
class PointStereoFactor : public ceres::SizedCostFunction<2, 1> {
 public:
  PointStereoFactor(const Vec2& uv_left, const Vec2& uv_right, const Pose& T_B_C0, const Pose& T_B_C1,
                    double sqrt_info);
  /// As if constructed anew with these arguments (FactorPool).
  void reset(const Vec2& uv_left, const Vec2& uv_right, const Pose& T_B_C0, const Pose& T_B_C1, double sqrt_info);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

  const Vec2& uvLeft() const { return uv_left_; }
  const Vec2& uvRight() const { return uv_right_; }
  const Pose& T_C1_C0() const { return T_C1_C0_; }
  double sqrtInfo() const { return sqrt_info_; }

 private:
  Vec2 uv_left_, uv_right_;
  Pose T_C1_C0_;
  double sqrt_info_;
};

/// Kind (3) with cam1 refined online: cam1 at T_B_C1 * S, S a correction block (7, PoseManifold; see
/// RigCorrectedFactor::stereoCorrected). Built with the extrinsics of an earlier correction S0 (T_B_C1 here contains
/// it), evaluated at S:
///     p_C1 = S^-1 S0 T_C1_C0 (f / rho),   dp/dt_S = -R_S^T,   dp/dphi_S = [p]x,   dp/drho = R_S^T R_S0 R_C1_C0 (-f / rho^2)
/// Blocks: inverse depth (1), S (7; its Jacobian in the tangent [dt, dphi] through TangentJacobians).
class PointStereoCorrectedFactor : public ceres::SizedCostFunction<2, 1, 7>, public TangentJacobians {
 public:
  PointStereoCorrectedFactor(const Vec2& uv_left, const Vec2& uv_right, const Pose& T_B_C0, const Pose& T_B_C1,
                             const Pose& S0, double sqrt_info);
  /// The kind (3) residual `f` (built with the correction S0), now with S as a block.
  PointStereoCorrectedFactor(const PointStereoFactor& f, const Pose& S0);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;
  bool evaluateTangentSpace(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  Vec2 uv_left_, uv_right_;
  Pose S0_T_C1_C0_;  // S0 * T_C1_C0
  double sqrt_info_;
};

/// Point of the host camera (uv_host at inverse depth rho) seen in the target camera, in pixels of error:
/// focal_px * |xy/z - uv_target|. Returns +infinity if the point is behind the target camera or rho <= 0.
/// For kind (3) pass the same body pose twice.
double pointReprojectionErrorPx(const Vec2& uv_host, const Vec2& uv_target, const Pose& T_B_Chost,
                                const Pose& T_B_Ctarget, const Pose& T_W_Bhost, const Pose& T_W_Btarget,
                                double inv_depth, double focal_px);

}  // namespace linnet
