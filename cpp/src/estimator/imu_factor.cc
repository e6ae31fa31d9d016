// IMU factor: residual and analytic Jacobians. See imu_factor.h for the residual definition.
#include "linnet/estimator/factors/imu_factor.h"

#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "linnet/core/error.h"
#include "linnet/core/pose.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {
namespace {

constexpr int kP = Preintegration::kP, kR = Preintegration::kR, kV = Preintegration::kV,
              kBa = Preintegration::kBa, kBg = Preintegration::kBg;

using Mat15x6 = Eigen::Matrix<double, 15, 6>;
using Mat15x9RowMajor = Eigen::Matrix<double, 15, 9, Eigen::RowMajor>;

// Everything the residual and its Jacobians share.
struct Terms {
  Vec3 p_i, v_i, b_a_i, b_g_i, p_j, v_j, b_a_j, b_g_j;
  Quat q_i, q_j;
  Mat3 Rt_i;      // R_i^T
  Vec3 dP, dV;    // p_j - p_i - v_i T - g T^2/2,  v_j - v_i - g T
  ImuDelta corr;  // bias-corrected deltas
  Vec3 phi;       // J_theta_bg dbg, the rotation correction
  Quat e;         // gamma_c^-1 q_i^-1 q_j
  Vec15 r;        // unweighted residual
};

Mat4 leftMultiplication(const Quat& q) { return quatLeft(q); }    // (w, x, y, z) order
Mat4 rightMultiplication(const Quat& q) { return quatRight(q); }  // (w, x, y, z) order

}  // namespace

ImuFactor::ImuFactor(const Preintegration& preintegration, const Vec3& g_W)
    : delta_(preintegration.delta()),
      bias_jacobian_(preintegration.jacobian()),
      b_a_lin_(preintegration.linearisedBa()),
      b_g_lin_(preintegration.linearisedBg()),
      sum_dt_(preintegration.sumDt()),
      g_W_(g_W) {
  if (preintegration.empty() || !(sum_dt_ > 0.0))
    throw UsageError("ImuFactor: the preintegration is empty (needs at least two samples spanning > 0 s)");
  sqrt_info_ = preintegration.sqrtInformation();
}

ImuFactor::ImuFactor(std::shared_ptr<const Preintegration> preintegration, const Vec3& g_W)
    : ImuFactor((preintegration ? *preintegration : throw UsageError("ImuFactor: null preintegration")),
                g_W) {}

ImuFactor::ImuFactor(std::shared_ptr<const Preintegration> preintegration, double gravity)
    : ImuFactor(std::move(preintegration), Vec3(0.0, 0.0, -gravity)) {}

namespace {

Terms computeTerms(const double* pose_i, const double* sb_i, const double* pose_j, const double* sb_j,
                   const ImuDelta& delta, const Mat15& J, const Vec3& b_a_lin, const Vec3& b_g_lin, double T,
                   const Vec3& g) {
  Terms t;
  t.p_i = posePosition(pose_i);
  t.q_i = poseRotation(pose_i);
  t.p_j = posePosition(pose_j);
  t.q_j = poseRotation(pose_j);
  t.v_i = Eigen::Map<const Vec3>(sb_i);
  t.b_a_i = Eigen::Map<const Vec3>(sb_i + 3);
  t.b_g_i = Eigen::Map<const Vec3>(sb_i + 6);
  t.v_j = Eigen::Map<const Vec3>(sb_j);
  t.b_a_j = Eigen::Map<const Vec3>(sb_j + 3);
  t.b_g_j = Eigen::Map<const Vec3>(sb_j + 6);

  const Vec3 dba = t.b_a_i - b_a_lin;
  const Vec3 dbg = t.b_g_i - b_g_lin;
  t.phi = J.block<3, 3>(kR, kBg) * dbg;
  t.corr.alpha = delta.alpha + J.block<3, 3>(kP, kBa) * dba + J.block<3, 3>(kP, kBg) * dbg;
  t.corr.beta = delta.beta + J.block<3, 3>(kV, kBa) * dba + J.block<3, 3>(kV, kBg) * dbg;
  t.corr.gamma = delta.gamma * expSO3(t.phi);

  t.Rt_i = t.q_i.toRotationMatrix().transpose();
  t.dP = t.p_j - t.p_i - t.v_i * T - 0.5 * g * T * T;
  t.dV = t.v_j - t.v_i - g * T;
  t.e = t.corr.gamma.conjugate() * (t.q_i.conjugate() * t.q_j);

  t.r.segment<3>(kP) = t.Rt_i * t.dP - t.corr.alpha;
  t.r.segment<3>(kR) = 2.0 * t.e.vec();
  t.r.segment<3>(kV) = t.Rt_i * t.dV - t.corr.beta;
  t.r.segment<3>(kBa) = t.b_a_j - t.b_a_i;
  t.r.segment<3>(kBg) = t.b_g_j - t.b_g_i;
  return t;
}

}  // namespace

Vec15 ImuFactor::unweightedResidual(const double* pose_i, const double* speed_bias_i, const double* pose_j,
                                    const double* speed_bias_j) const {
  return computeTerms(pose_i, speed_bias_i, pose_j, speed_bias_j, delta_, bias_jacobian_, b_a_lin_, b_g_lin_,
                      sum_dt_, g_W_)
      .r;
}

bool ImuFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const double T = sum_dt_;
  const Terms t = computeTerms(parameters[0], parameters[1], parameters[2], parameters[3], delta_,
                               bias_jacobian_, b_a_lin_, b_g_lin_, T, g_W_);
  Eigen::Map<Vec15> r(residuals);
  r = sqrt_info_ * t.r;
  if (jacobians == nullptr) return true;

  const Mat3 I3 = Mat3::Identity();
  const Mat15& J = bias_jacobian_;

  if (jacobians[0] != nullptr) {  // pose_i: [dp_i, dtheta_i]
    Mat15x6 Jt = Mat15x6::Zero();
    Jt.block<3, 3>(kP, 0) = -t.Rt_i;
    Jt.block<3, 3>(kP, 3) = skew(t.Rt_i * t.dP);
    // e(dtheta) = gamma_c^-1 Exp(-dtheta) q_i^-1 q_j  ->  d(2 vec e) = -[L(gamma_c^-1) R(q_i^-1 q_j)]_xyz,xyz
    Jt.block<3, 3>(kR, 3) =
        -(leftMultiplication(t.corr.gamma.conjugate()) * rightMultiplication(t.q_i.conjugate() * t.q_j))
             .bottomRightCorner<3, 3>();
    Jt.block<3, 3>(kV, 3) = skew(t.Rt_i * t.dV);
    const Mat15x6 Jw = sqrt_info_ * Jt;
    tangentToAmbientPose<15>(Jw, parameters[0], jacobians[0]);
  }
  if (jacobians[1] != nullptr) {  // speed-bias_i: [v_i, b_a_i, b_g_i]
    Mat15x9RowMajor Js = Mat15x9RowMajor::Zero();
    Js.block<3, 3>(kP, 0) = -t.Rt_i * T;
    Js.block<3, 3>(kP, 3) = -J.block<3, 3>(kP, kBa);
    Js.block<3, 3>(kP, 6) = -J.block<3, 3>(kP, kBg);
    // gamma_c(b_g + d) ~= gamma_c Exp(Jr(phi) J_theta_bg d)  ->  e ~= Exp(-Jr J d) e
    Js.block<3, 3>(kR, 6) = -rightMultiplication(t.e).bottomRightCorner<3, 3>() * rightJacobianSO3(t.phi) *
                            J.block<3, 3>(kR, kBg);
    Js.block<3, 3>(kV, 0) = -t.Rt_i;
    Js.block<3, 3>(kV, 3) = -J.block<3, 3>(kV, kBa);
    Js.block<3, 3>(kV, 6) = -J.block<3, 3>(kV, kBg);
    Js.block<3, 3>(kBa, 3) = -I3;
    Js.block<3, 3>(kBg, 6) = -I3;
    Eigen::Map<Mat15x9RowMajor> out(jacobians[1]);
    out = sqrt_info_ * Js;
  }
  if (jacobians[2] != nullptr) {  // pose_j
    Mat15x6 Jt = Mat15x6::Zero();
    Jt.block<3, 3>(kP, 0) = t.Rt_i;
    // e(dtheta) = e Exp(dtheta)  ->  d(2 vec e) = [L(e)]_xyz,xyz
    Jt.block<3, 3>(kR, 3) = leftMultiplication(t.e).bottomRightCorner<3, 3>();
    const Mat15x6 Jw = sqrt_info_ * Jt;
    tangentToAmbientPose<15>(Jw, parameters[2], jacobians[2]);
  }
  if (jacobians[3] != nullptr) {  // speed-bias_j
    Mat15x9RowMajor Js = Mat15x9RowMajor::Zero();
    Js.block<3, 3>(kV, 0) = t.Rt_i;
    Js.block<3, 3>(kBa, 3) = I3;
    Js.block<3, 3>(kBg, 6) = I3;
    Eigen::Map<Mat15x9RowMajor> out(jacobians[3]);
    out = sqrt_info_ * Js;
  }
  return true;
}

}  // namespace linnet
