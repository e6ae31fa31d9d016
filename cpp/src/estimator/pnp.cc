#include "linnet/estimator/pnp.h"

#include <array>
#include <cmath>

#include <ceres/autodiff_cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>
#include <ceres/rotation.h>
#include <ceres/solver.h>

#include "linnet/estimator/manifolds.h"

namespace linnet {

namespace {

// Reprojection of a fixed world point in cam0 of the pose block [p, q xyzw] (T_W_B).
struct PnpError {
  PnpError(const Vec3& p_W, const Vec2& uv, const Pose& T_B_C, double scale)
      : p_W_(p_W), uv_(uv), R_C_B_(T_B_C.inverse().R()), t_C_B_(T_B_C.inverse().p), scale_(scale) {}

  template <class T>
  bool operator()(const T* pose, T* residual) const {
    const Eigen::Matrix<T, 3, 1> p(pose[0], pose[1], pose[2]);
    const Eigen::Quaternion<T> q(pose[6], pose[3], pose[4], pose[5]);  // w, x, y, z
    const Eigen::Matrix<T, 3, 1> p_B = q.conjugate() * (p_W_.cast<T>() - p);
    const Eigen::Matrix<T, 3, 1> p_C = R_C_B_.cast<T>() * p_B + t_C_B_.cast<T>();
    residual[0] = T(scale_) * (p_C.x() / p_C.z() - T(uv_.x()));
    residual[1] = T(scale_) * (p_C.y() / p_C.z() - T(uv_.y()));
    return true;
  }

  Vec3 p_W_;
  Vec2 uv_;
  Mat3 R_C_B_;
  Vec3 t_C_B_;
  double scale_;
};

double errorPx(const Vec3& p_W, const Vec2& uv, const Pose& T_W_C, double f) {
  const Vec3 c = T_W_C.inverse() * p_W;
  if (c.z() <= 1e-6) return 1e9;
  return f * (c.head<2>() / c.z() - uv).norm();
}

}  // namespace

PnpResult refinePosePnp(const std::vector<Vec3>& p_W, const std::vector<Vec2>& uv, const Pose& T_B_C0,
                        double focal_length, double outlier_px, Pose* T_W_B) {
  PnpResult result;
  std::vector<bool> keep(p_W.size(), true);
  std::array<double, 7> block{};
  setPose(*T_W_B, block.data());
  PoseManifold manifold;
  for (int pass = 0; pass < 2; ++pass) {
    ceres::Problem::Options po;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    problem.AddParameterBlock(block.data(), 7, &manifold);
    int n = 0;
    for (std::size_t i = 0; i < p_W.size(); ++i) {
      if (!keep[i]) continue;
      auto* cost = new ceres::AutoDiffCostFunction<PnpError, 2, 7>(new PnpError(p_W[i], uv[i], T_B_C0, focal_length));
      problem.AddResidualBlock(cost, new ceres::HuberLoss(1.0), block.data());
      ++n;
    }
    if (n < 4) return result;
    ceres::Solver::Options so;
    so.max_num_iterations = 10;
    so.linear_solver_type = ceres::DENSE_QR;
    so.num_threads = 1;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem, &summary);
    // Drop gross outliers after the first pass.
    const Pose T_W_C = poseFromBlock(block.data()) * T_B_C0;
    for (std::size_t i = 0; i < p_W.size(); ++i)
      if (keep[i] && errorPx(p_W[i], uv[i], T_W_C, focal_length) > outlier_px) keep[i] = false;
  }
  const Pose T_W_C = poseFromBlock(block.data()) * T_B_C0;
  double sq = 0.0;
  for (std::size_t i = 0; i < p_W.size(); ++i) {
    if (!keep[i]) continue;
    const double e = errorPx(p_W[i], uv[i], T_W_C, focal_length);
    sq += e * e;
    ++result.inliers;
  }
  if (result.inliers < 4) return result;
  result.rms_px = std::sqrt(sq / result.inliers);
  result.ok = true;
  *T_W_B = poseFromBlock(block.data());
  return result;
}

}  // namespace linnet
