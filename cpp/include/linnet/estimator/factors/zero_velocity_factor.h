// Priors of a frame detected at rest (ZeroVelocityOptions):
//  - ZeroVelocityFactor: r = v_W / sigma over the frame's speed-bias block [v_W, b_a, b_g] (9); linear, exact
//    Jacobian [I / sigma, 0, 0].
//  - NoMotionFactor between the previous window frame i and the resting frame j: the body did not move,
//        r = [(p_j - p_i) / sigma_p;  Log(R_i^T R_j) / sigma_theta]
//    with tangent Jacobians (PoseManifold: p <- p + dp, R <- R Exp(dth)), theta = Log(R_i^T R_j):
//        d r_theta / d th_j = Jr^-1(theta),  d r_theta / d th_i = -Jr^-1(theta) R_j^T R_i.
//    At rest the frames are not keyframes and are dropped, so the prior ties each new frame to the last kept one
//    instead of leaving it to a preintegration of up to keyframe.max_gap_s.
#pragma once

#include <ceres/sized_cost_function.h>

namespace linnet {

class ZeroVelocityFactor : public ceres::SizedCostFunction<3, 9> {
 public:
  explicit ZeroVelocityFactor(double velocity_sigma) : inv_sigma_(1.0 / velocity_sigma) {}

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double inv_sigma_;
};

class NoMotionFactor : public ceres::SizedCostFunction<6, 7, 7> {
 public:
  NoMotionFactor(double position_sigma_m, double rotation_sigma_rad)
      : inv_p_(1.0 / position_sigma_m), inv_r_(1.0 / rotation_sigma_rad) {}

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

 private:
  double inv_p_, inv_r_;
};

}  // namespace linnet
