// The IMU residual between two window frames i and j (DESIGN B1; VINS-Mono, Qin et al. 2018; Forster et al.
// 2017).
//
// Parameter blocks: pose_i (7), speed-bias_i (9 = [v_W, b_a, b_g]), pose_j (7), speed-bias_j (9); see
// manifolds.h. Residual (15), in the preintegration's error-state order:
//   r_p     = R_i^T (p_j - p_i - v_i T - g_W T^2 / 2) - alpha(b_i)
//   r_theta = 2 [gamma(b_i)^-1 q_i^-1 q_j]_xyz
//   r_v     = R_i^T (v_j - v_i - g_W T) - beta(b_i)
//   r_ba    = b_a,j - b_a,i
//   r_bg    = b_g,j - b_g,i
// where alpha(b), beta(b), gamma(b) are the first-order bias-corrected deltas
// (Preintegration::correctedDelta) at the biases of frame i. The residual is whitened by S = upper-triangular
// square root of the inverse preintegration covariance (S^T S = P^-1). Jacobians are analytic (exact for this
// residual, including the right Jacobian of the gyroscope bias correction), formed in the tangent spaces and
// mapped to the pose blocks' ambient coordinates.
//
// The factor copies what it needs from the preintegration at construction; repropagating the preintegration
// afterwards does not change an existing factor (build a new one).
#pragma once

#include <memory>

#include <ceres/sized_cost_function.h>

#include "linnet/core/types.h"
#include "linnet/imu/preintegration.h"

namespace linnet {

class ImuFactor : public ceres::SizedCostFunction<15, 7, 9, 7, 9> {
 public:
  /// g_W is the gravity vector in W (usually (0, 0, -9.81)). Throws UsageError if the preintegration is empty
  /// or its covariance is zero.
  ImuFactor(std::shared_ptr<const Preintegration> preintegration, const Vec3& g_W);
  ImuFactor(const Preintegration& preintegration, const Vec3& g_W);
  /// Gravity (0, 0, -gravity) from a magnitude.
  ImuFactor(std::shared_ptr<const Preintegration> preintegration, double gravity);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

  /// The unwhitened residual for given blocks (for diagnostics and tests).
  Vec15 unweightedResidual(const double* pose_i, const double* speed_bias_i, const double* pose_j,
                           const double* speed_bias_j) const;

  const Mat15& sqrtInformation() const { return sqrt_info_; }
  double sumDt() const { return sum_dt_; }

 private:
  ImuDelta delta_;       // at the linearisation biases
  Mat15 bias_jacobian_;  // Preintegration::jacobian()
  Vec3 b_a_lin_, b_g_lin_;
  double sum_dt_ = 0.0;  // s
  Vec3 g_W_;
  Mat15 sqrt_info_;
};

}  // namespace linnet
