// PriorFactor: r + J * (x [-] x0) with exact Jacobians through each block's manifold (see prior_factor.h).
#include "linnet/estimator/factors/prior_factor.h"

#include <string>
#include <utility>

#include <Eigen/Dense>

#include "linnet/core/error.h"
#include "linnet/core/pose.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// d Minus(Plus(x, d), x0) / dd at d = 0 for a general manifold, by central differences of the manifold's own
/// Plus / Minus (step 1e-6: truncation ~1e-12, round-off ~1e-10 on unit-scale blocks).
bool tangentDifferenceJacobianNumeric(const ceres::Manifold& manifold, const double* x, const double* x0,
                                      Eigen::MatrixXd* T) {
  const int a = manifold.AmbientSize(), t = manifold.TangentSize();
  constexpr double kStep = 1e-6;
  Eigen::VectorXd delta = Eigen::VectorXd::Zero(t), xp(a), xm(a), dp(t), dm(t);
  T->resize(t, t);
  for (int j = 0; j < t; ++j) {
    delta(j) = kStep;
    if (!manifold.Plus(x, delta.data(), xp.data())) return false;
    delta(j) = -kStep;
    if (!manifold.Plus(x, delta.data(), xm.data())) return false;
    delta(j) = 0.0;
    if (!manifold.Minus(xp.data(), x0, dp.data()) || !manifold.Minus(xm.data(), x0, dm.data())) return false;
    T->col(j) = (dp - dm) / (2.0 * kStep);
  }
  return true;
}

/// The same derivative for PoseManifold, analytically: Minus(y, x0) = (p_y - p0, Log(q0^-1 q_y)) and
/// Plus(x, d) = (p + dp, q Exp(dtheta)), so it is blockdiag(I, Jr^-1(Log(q0^-1 q))) (right Jacobian of
/// SO(3)).
Eigen::MatrixXd tangentDifferenceJacobianPose(const double* x, const double* x0) {
  Eigen::MatrixXd T = Eigen::MatrixXd::Identity(kPoseTangentSize, kPoseTangentSize);
  const Vec3 phi = logSO3(poseRotation(x0).conjugate() * poseRotation(x));
  T.bottomRightCorner<3, 3>() = rightJacobianInvSO3(phi);
  return T;
}

}  // namespace

int MarginalizationPrior::indexOf(BlockKey key) const {
  for (std::size_t i = 0; i < keys.size(); ++i)
    if (keys[i] == key) return static_cast<int>(i);
  return -1;
}

PriorFactor::PriorFactor(std::shared_ptr<const MarginalizationPrior> prior) : prior_(std::move(prior)) {
  if (!prior_) throw UsageError("PriorFactor: null prior");
  const MarginalizationPrior& p = *prior_;
  const std::size_t nb = p.keys.size();
  if (p.ambient_sizes.size() != nb || p.tangent_sizes.size() != nb || p.tangent_offsets.size() != nb ||
      p.x0.size() != nb || p.manifolds.size() != nb)
    throw UsageError("PriorFactor: the prior's per-block vectors differ in length");
  if (p.J.rows() == 0 || p.J.rows() != p.r.size())
    throw UsageError("PriorFactor: the prior has " + std::to_string(p.J.rows()) + " rows in J and " +
                     std::to_string(p.r.size()) + " in r");
  int cols = 0;
  for (std::size_t k = 0; k < nb; ++k) {
    if (p.tangent_offsets[k] != cols || static_cast<int>(p.x0[k].size()) != p.ambient_sizes[k])
      throw UsageError("PriorFactor: inconsistent layout of block " + std::to_string(k) + " (key " +
                       std::to_string(p.keys[k]) + ")");
    cols += p.tangent_sizes[k];
    mutable_parameter_block_sizes()->push_back(p.ambient_sizes[k]);
  }
  if (cols != p.J.cols())
    throw UsageError("PriorFactor: blocks span " + std::to_string(cols) + " tangent columns but J has " +
                     std::to_string(p.J.cols()));
  set_num_residuals(static_cast<int>(p.J.rows()));
}

bool PriorFactor::Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
  const MarginalizationPrior& p = *prior_;
  const std::size_t nb = p.keys.size();
  const Eigen::Index rows = p.J.rows();
  Eigen::Map<Eigen::VectorXd> res(residuals, rows);
  res = p.r;
  for (std::size_t k = 0; k < nb; ++k) {
    const int t = p.tangent_sizes[k], a = p.ambient_sizes[k];
    const auto Jk = p.J.middleCols(p.tangent_offsets[k], t);
    const ceres::Manifold* manifold = p.manifolds[k];
    Eigen::VectorXd dx(t);
    if (manifold == nullptr) {
      dx = Eigen::Map<const Eigen::VectorXd>(parameters[k], a) -
           Eigen::Map<const Eigen::VectorXd>(p.x0[k].data(), a);
    } else if (!manifold->Minus(parameters[k], p.x0[k].data(), dx.data())) {
      return false;
    }
    res.noalias() += Jk * dx;
    if (jacobians == nullptr || jacobians[k] == nullptr) continue;
    Eigen::Map<RowMatrix> jac(jacobians[k], rows, a);
    if (manifold == nullptr) {
      jac = Jk;
      continue;
    }
    // d res / d x_ambient = J_k * [d Minus(Plus(x, d), x0) / dd] * MinusJacobian(x); Ceres multiplies it by
    // PlusJacobian(x) and MinusJacobian(x) * PlusJacobian(x) = I, which gives the exact tangent Jacobian.
    Eigen::MatrixXd T;
    if (dynamic_cast<const PoseManifold*>(manifold) != nullptr) {
      T = tangentDifferenceJacobianPose(parameters[k], p.x0[k].data());
    } else if (!tangentDifferenceJacobianNumeric(*manifold, parameters[k], p.x0[k].data(), &T)) {
      return false;
    }
    RowMatrix minus_jac(t, a);
    if (!manifold->MinusJacobian(parameters[k], minus_jac.data())) return false;
    jac = Jk * T * minus_jac;
  }
  return true;
}

}  // namespace linnet
