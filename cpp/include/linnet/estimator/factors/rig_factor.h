// Online camera-IMU extrinsics: a visual residual seen through a correction of the calibrated rig.
//
// The stereo pair is calibrated well relative to itself (the target is seen by both cameras at once) and less well
// relative to the IMU (that part is observed only through the motion). The estimator therefore refines one rigid
// correction T_B_R of the whole rig on the body side, common to both cameras (as OKVIS and VINS-Mono refine T_B_C,
// but with the stereo baseline kept): the cameras' extrinsics are T_B_R * T_B_Ci, with T_B_Ci the calibration's.
//
// A visual residual built with the extrinsics in use when it was made, E0 = T_B_R0 * T_B_Ci, is wrapped so that
// each of its body poses T_W_Bk is replaced by the "rig pose" T_W_Bk * T_B_R * T_B_R0^-1; the inner factor then
// sees T_W_Bk * T_B_R * T_B_Ci, exactly. With the tangent convention of PoseManifold (p <- p + dp, R <- R Exp(dth))
// and M = T_B_R * D, D = T_B_R0^-1, the rig pose T_W_Rk = T_W_Bk * M moves as
//     body:       dp_R = dp - R_Bk [t_M]x dth,            dth_R = R_M^T dth
//     correction: dp_R = R_Bk dt - R_Bk R_BR [t_D]x dth,  dth_R = R_D^T dth
// and the inner factor's tangent Jacobians are chained through these. Residuals without a pose block (the
// same-frame stereo point residual) do not depend on a common correction and are not wrapped.
#pragma once

#include <memory>
#include <vector>

#include <ceres/cost_function.h>

#include "linnet/core/pose.h"

namespace linnet {

class RigCorrectedFactor : public ceres::CostFunction {
 public:
  /// inner: a residual whose blocks `pose_blocks` (indices) are body poses (7, PoseManifold); T_B_R0: the correction
  /// that inner's extrinsics already contain. The wrapped factor takes inner's blocks followed by the correction
  /// T_B_R (7, PoseManifold).
  RigCorrectedFactor(std::shared_ptr<ceres::CostFunction> inner, std::vector<int> pose_blocks, const Pose& T_B_R0);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

  const ceres::CostFunction& inner() const { return *inner_; }

 private:
  std::shared_ptr<ceres::CostFunction> inner_;
  std::vector<int> pose_blocks_;
  Pose D_;  // T_B_R0^-1
};

}  // namespace linnet
