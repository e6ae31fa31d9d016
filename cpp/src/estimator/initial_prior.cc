#include "linnet/estimator/initial_prior.h"

namespace linnet {

std::shared_ptr<const MarginalizationPrior> makeInitialPrior(const WindowFrame& f, const InitialPriorSigmas& s,
                                                             const ceres::Manifold* pose_manifold) {
  auto p = std::make_shared<MarginalizationPrior>();
  p->keys = {frameBlockKey(f.id, BlockKind::kPose), frameBlockKey(f.id, BlockKind::kSpeedBias)};
  p->ambient_sizes = {7, 9};
  p->tangent_sizes = {6, 9};
  p->tangent_offsets = {0, 6};
  p->x0 = {std::vector<double>(f.pose.begin(), f.pose.end()),
           std::vector<double>(f.speed_bias.begin(), f.speed_bias.end())};
  p->manifolds = {pose_manifold, nullptr};
  const bool with_velocity = s.velocity > 0.0;
  const int rows = 4 + (with_velocity ? 3 : 0) + 6;
  p->J = Eigen::MatrixXd::Zero(rows, 15);
  p->r = Eigen::VectorXd::Zero(rows);
  int row = 0;
  // Position (tangent dp is in W).
  p->J.block<3, 3>(row, 0) = Mat3::Identity() / s.position_m;
  row += 3;
  // Yaw: the tangent rotation is on the right (body frame); its z component in W is e_z^T R dtheta.
  p->J.block<1, 3>(row, 3) = (f.T_W_B().R().transpose() * Vec3::UnitZ()).transpose() / s.yaw_rad;
  row += 1;
  if (with_velocity) {
    p->J.block<3, 3>(row, 6) = Mat3::Identity() / s.velocity;
    row += 3;
  }
  p->J.block<3, 3>(row, 9) = Mat3::Identity() / s.acc_bias;
  p->J.block<3, 3>(row + 3, 12) = Mat3::Identity() / s.gyr_bias;
  return p;
}

}  // namespace linnet
