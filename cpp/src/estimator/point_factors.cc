// Point residuals (DESIGN B1) with analytic Jacobians; derivation in the comments of evaluateTangent.
#include "linnet/estimator/factors/point_factors.h"

#include <cmath>
#include <limits>

#include "linnet/estimator/manifolds.h"
#include "linnet/geometry/projection.h"

namespace linnet {

PointReprojectionFactor::PointReprojectionFactor(const Vec2& uv_host, const Vec2& uv_target,
                                                 const Pose& T_B_Chost, const Pose& T_B_Ctarget,
                                                 double sqrt_info) {
  reset(uv_host, uv_target, T_B_Chost, T_B_Ctarget, sqrt_info);
}

void PointReprojectionFactor::reset(const Vec2& uv_host, const Vec2& uv_target, const Pose& T_B_Chost,
                                    const Pose& T_B_Ctarget, double sqrt_info) {
  uv_host_ = uv_host;
  uv_target_ = uv_target;
  T_B_Ch_ = T_B_Chost;
  T_B_Ct_ = T_B_Ctarget;
  sqrt_info_ = sqrt_info;
}

bool PointReprojectionFactor::evaluateTangent(const Pose& T_W_Bi, const Pose& T_W_Bj, double inv_depth,
                                              Vec2* residual, Eigen::Matrix<double, 2, 6>* J_pose_i,
                                              Eigen::Matrix<double, 2, 6>* J_pose_j,
                                              Vec2* J_inv_depth) const {
  const Vec3 f(uv_host_.x(), uv_host_.y(), 1.0);
  const Vec3 p_Ch = f / inv_depth;
  const Vec3 p_Bi = T_B_Ch_ * p_Ch;
  const Vec3 p_W = T_W_Bi * p_Bi;
  const Mat3 R_Bj_W = T_W_Bj.R().transpose();
  const Vec3 p_Bj = R_Bj_W * (p_W - T_W_Bj.p);
  const Mat3 R_Ct_B = T_B_Ct_.R().transpose();
  const Vec3 p_Ct = R_Ct_B * (p_Bj - T_B_Ct_.p);
  const Vec2 r = sqrt_info_ * (Vec2(p_Ct.x() / p_Ct.z(), p_Ct.y() / p_Ct.z()) - uv_target_);
  if (!r.allFinite()) return false;
  if (residual != nullptr) *residual = r;
  if (J_pose_i == nullptr && J_pose_j == nullptr && J_inv_depth == nullptr) return true;

  // A = dr/dp_Bj. With right perturbations R <- R Exp(dtheta), p <- p + dp:
  //   p_W  = R_i Exp(dth_i) p_Bi + p_i        -> dp_W/dp_i = I, dp_W/dth_i = -R_i [p_Bi]x
  //   p_Bj = Exp(-dth_j) R_j^T (p_W - p_j)    -> dp_Bj/dp_j = -R_j^T, dp_Bj/dth_j = [p_Bj]x
  //   p_Ch = f / rho                          -> dp_Ch/drho = -f / rho^2
  const Eigen::Matrix<double, 2, 3> D = sqrt_info_ * projectionJacobian(p_Ct);
  const Eigen::Matrix<double, 2, 3> A = D * R_Ct_B;
  const Eigen::Matrix<double, 2, 3> A_W = A * R_Bj_W;  // dr/dp_W
  if (J_pose_i != nullptr) {
    J_pose_i->leftCols<3>() = A_W;
    J_pose_i->rightCols<3>() = -A_W * T_W_Bi.R() * skew(p_Bi);
  }
  if (J_pose_j != nullptr) {
    J_pose_j->leftCols<3>() = -A_W;
    J_pose_j->rightCols<3>() = A * skew(p_Bj);
  }
  if (J_inv_depth != nullptr) *J_inv_depth = A_W * T_W_Bi.R() * T_B_Ch_.R() * (-f / (inv_depth * inv_depth));
  return true;
}

bool PointReprojectionFactor::evaluateTangentSpace(double const* const* parameters, double* residuals,
                                                   double** jacobians) const {
  const bool want_i = jacobians != nullptr && jacobians[0] != nullptr;
  const bool want_j = jacobians != nullptr && jacobians[1] != nullptr;
  const bool want_rho = jacobians != nullptr && jacobians[2] != nullptr;
  Vec2 r, J_rho;
  Eigen::Matrix<double, 2, 6> J_i, J_j;
  if (!evaluateTangent(poseFromBlock(parameters[0]), poseFromBlock(parameters[1]), parameters[2][0], &r,
                       want_i ? &J_i : nullptr, want_j ? &J_j : nullptr, want_rho ? &J_rho : nullptr))
    return false;
  residuals[0] = r.x();
  residuals[1] = r.y();
  using Tangent = Eigen::Matrix<double, 2, 6, Eigen::RowMajor>;
  if (want_i) Eigen::Map<Tangent>{jacobians[0]} = J_i;
  if (want_j) Eigen::Map<Tangent>{jacobians[1]} = J_j;
  if (want_rho) {
    jacobians[2][0] = J_rho.x();
    jacobians[2][1] = J_rho.y();
  }
  return true;
}

bool PointReprojectionFactor::Evaluate(double const* const* parameters, double* residuals,
                                       double** jacobians) const {
  return evaluateThroughTangent(*this, parameter_block_sizes(), num_residuals(), parameters, residuals, jacobians);
}

PointStereoFactor::PointStereoFactor(const Vec2& uv_left, const Vec2& uv_right, const Pose& T_B_C0,
                                     const Pose& T_B_C1, double sqrt_info) {
  reset(uv_left, uv_right, T_B_C0, T_B_C1, sqrt_info);
}

void PointStereoFactor::reset(const Vec2& uv_left, const Vec2& uv_right, const Pose& T_B_C0, const Pose& T_B_C1,
                              double sqrt_info) {
  uv_left_ = uv_left;
  uv_right_ = uv_right;
  T_C1_C0_ = T_B_C1.inverse() * T_B_C0;
  sqrt_info_ = sqrt_info;
}

bool PointStereoFactor::Evaluate(double const* const* parameters, double* residuals,
                                 double** jacobians) const {
  const double inv_depth = parameters[0][0];
  const Vec3 f(uv_left_.x(), uv_left_.y(), 1.0);
  const Vec3 p_C1 = T_C1_C0_ * (f / inv_depth);
  const Vec2 r = sqrt_info_ * (Vec2(p_C1.x() / p_C1.z(), p_C1.y() / p_C1.z()) - uv_right_);
  if (!r.allFinite()) return false;
  residuals[0] = r.x();
  residuals[1] = r.y();
  if (jacobians != nullptr && jacobians[0] != nullptr) {
    // dr/drho = D * R_C1_C0 * (-f / rho^2)
    const Eigen::Matrix<double, 2, 3> D = sqrt_info_ * projectionJacobian(p_C1);
    const Vec2 J = D * T_C1_C0_.R() * (-f / (inv_depth * inv_depth));
    jacobians[0][0] = J.x();
    jacobians[0][1] = J.y();
  }
  return true;
}

PointStereoCorrectedFactor::PointStereoCorrectedFactor(const Vec2& uv_left, const Vec2& uv_right, const Pose& T_B_C0,
                                                       const Pose& T_B_C1, const Pose& S0, double sqrt_info)
    : uv_left_(uv_left), uv_right_(uv_right), S0_T_C1_C0_(S0 * (T_B_C1.inverse() * T_B_C0)), sqrt_info_(sqrt_info) {}

PointStereoCorrectedFactor::PointStereoCorrectedFactor(const PointStereoFactor& f, const Pose& S0)
    : uv_left_(f.uvLeft()), uv_right_(f.uvRight()), S0_T_C1_C0_(S0 * f.T_C1_C0()), sqrt_info_(f.sqrtInfo()) {}

bool PointStereoCorrectedFactor::evaluateTangentSpace(double const* const* parameters, double* residuals,
                                                      double** jacobians) const {
  const double inv_depth = parameters[0][0];
  const Pose S = poseFromBlock(parameters[1]);
  const Mat3 R_S_t = S.R().transpose();
  const Vec3 f(uv_left_.x(), uv_left_.y(), 1.0);
  const Vec3 p = R_S_t * (S0_T_C1_C0_ * (f / inv_depth) - S.p);
  const Vec2 r = sqrt_info_ * (Vec2(p.x() / p.z(), p.y() / p.z()) - uv_right_);
  if (!r.allFinite()) return false;
  residuals[0] = r.x();
  residuals[1] = r.y();
  if (jacobians == nullptr) return true;
  const Eigen::Matrix<double, 2, 3> D = sqrt_info_ * projectionJacobian(p);
  if (jacobians[0] != nullptr) {
    const Vec2 J = D * R_S_t * S0_T_C1_C0_.R() * (-f / (inv_depth * inv_depth));
    jacobians[0][0] = J.x();
    jacobians[0][1] = J.y();
  }
  if (jacobians[1] != nullptr) {
    Eigen::Map<Eigen::Matrix<double, 2, 6, Eigen::RowMajor>> J(jacobians[1]);
    J.leftCols<3>() = -D * R_S_t;
    J.rightCols<3>() = D * skew(p);
  }
  return true;
}

bool PointStereoCorrectedFactor::Evaluate(double const* const* parameters, double* residuals,
                                          double** jacobians) const {
  return evaluateThroughTangent(*this, parameter_block_sizes(), num_residuals(), parameters, residuals, jacobians);
}

double pointReprojectionErrorPx(const Vec2& uv_host, const Vec2& uv_target, const Pose& T_B_Chost,
                                const Pose& T_B_Ctarget, const Pose& T_W_Bhost, const Pose& T_W_Btarget,
                                double inv_depth, double focal_px) {
  if (!(inv_depth > 0.0)) return std::numeric_limits<double>::infinity();
  const Vec3 p_Ch = Vec3(uv_host.x(), uv_host.y(), 1.0) / inv_depth;
  const Vec3 p_Ct = (T_W_Btarget * T_B_Ctarget).inverse() * ((T_W_Bhost * T_B_Chost) * p_Ch);
  if (!(p_Ct.z() > 1e-9)) return std::numeric_limits<double>::infinity();
  const double err = focal_px * (Vec2(p_Ct.x() / p_Ct.z(), p_Ct.y() / p_Ct.z()) - uv_target).norm();
  return std::isfinite(err) ? err : std::numeric_limits<double>::infinity();
}

}  // namespace linnet
