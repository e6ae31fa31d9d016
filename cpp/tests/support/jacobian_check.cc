// Generic analytic-vs-numeric Jacobian checker through manifolds. See jacobian_check.h.
#include "support/jacobian_check.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "linnet/estimator/factors/tangent_jacobians.h"

namespace linnet::testing {
namespace {

using RowMajorMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// One evaluation of the cost function with some Jacobians requested.
struct Evaluation {
  bool ok = false;
  Eigen::VectorXd residuals;
  std::vector<RowMajorMatrix> jacobians;  // rows x ambient; empty matrix if not requested
};

// With `tangent_path`, through TangentJacobians::evaluateTangentSpace: rows x 6 for the pose blocks (`pose`).
Evaluation evaluate(const ceres::CostFunction& f, const std::vector<const double*>& params,
                    const std::vector<bool>& want, const TangentJacobians* tangent_path = nullptr,
                    const std::vector<bool>& pose = {}) {
  const int rows = f.num_residuals();
  const std::vector<int32_t>& sizes = f.parameter_block_sizes();
  Evaluation e;
  e.residuals = Eigen::VectorXd::Constant(rows, std::numeric_limits<double>::quiet_NaN());
  e.jacobians.resize(sizes.size());
  std::vector<double*> jac_ptrs(sizes.size(), nullptr);
  bool any = false;
  for (size_t b = 0; b < sizes.size(); ++b) {
    if (!want[b]) continue;
    const int cols = tangent_path != nullptr && pose[b] ? 6 : sizes[b];
    e.jacobians[b] = RowMajorMatrix::Constant(rows, cols, std::numeric_limits<double>::quiet_NaN());
    jac_ptrs[b] = e.jacobians[b].data();
    any = true;
  }
  double** J = any ? jac_ptrs.data() : nullptr;
  e.ok = tangent_path != nullptr ? tangent_path->evaluateTangentSpace(params.data(), e.residuals.data(), J)
                                 : f.Evaluate(params.data(), e.residuals.data(), J);
  return e;
}

double maxAbsDiff(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  if (a.size() == 0) return 0.0;
  return (a - b).cwiseAbs().maxCoeff();
}

bool sameNumbers(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  // Bit-level equality is not required (a factor may take another code path); 1e-12 relative is.
  if (a.rows() != b.rows() || a.cols() != b.cols()) return false;
  if (!a.allFinite() || !b.allFinite()) return false;
  const double scale = std::max(1.0, a.cwiseAbs().maxCoeff());
  return maxAbsDiff(a, b) <= 1e-12 * scale;
}

}  // namespace

double JacobianCheckResult::maxAbsError() const {
  double m = 0.0;
  for (const auto& b : blocks) m = std::max(m, b.max_abs_error);
  return m;
}

double JacobianCheckResult::maxRelError() const {
  double m = 0.0;
  for (const auto& b : blocks) m = std::max(m, b.max_rel_error);
  return m;
}

bool JacobianCheckResult::ok(double tol) const {
  if (!evaluated || !residuals_consistent) return false;
  for (const auto& b : blocks)
    if (!b.finite || !(b.max_rel_error <= tol)) return false;
  return true;
}

std::string JacobianCheckResult::describe(double tol, bool matrices) const {
  std::ostringstream os;
  os << std::setprecision(4);
  if (!problem.empty()) os << "problem: " << problem << "\n";
  for (const auto& b : blocks) {
    os << "block " << b.block << " (ambient " << b.ambient_size << ", tangent " << b.tangent_size
       << "): max abs error " << b.max_abs_error << ", max rel error " << b.max_rel_error;
    if (!b.finite) os << ", NON-FINITE or unwritten analytic entries";
    if (b.worst_row >= 0)
      os << ", worst at (" << b.worst_row << ", " << b.worst_col << ") analytic "
         << b.analytic(b.worst_row, b.worst_col) << " numeric " << b.numeric(b.worst_row, b.worst_col);
    os << "\n";
    if (matrices && (!b.finite || b.max_rel_error > tol)) {
      const Eigen::IOFormat fmt(6, 0, " ", "\n", "  [", "]");
      os << " analytic:\n" << b.analytic.format(fmt) << "\n numeric:\n" << b.numeric.format(fmt) << "\n";
      if (b.tangent_space.size() != 0) os << " analytic, tangent-space path:\n" << b.tangent_space.format(fmt) << "\n";
    }
  }
  return os.str();
}

JacobianCheckResult checkJacobians(const ceres::CostFunction& f, const std::vector<double*>& params,
                                   const std::vector<const ceres::Manifold*>& manifolds, double step) {
  JacobianCheckResult result;
  const std::vector<int32_t>& sizes = f.parameter_block_sizes();
  const size_t nb = sizes.size();
  const int rows = f.num_residuals();
  if (params.size() != nb) {
    result.problem = "got " + std::to_string(params.size()) + " parameter blocks, the cost function has " +
                     std::to_string(nb);
    return result;
  }
  if (!manifolds.empty() && manifolds.size() != nb) {
    result.problem =
        "got " + std::to_string(manifolds.size()) + " manifolds for " + std::to_string(nb) + " blocks";
    return result;
  }
  auto manifoldOf = [&](size_t b) -> const ceres::Manifold* {
    return manifolds.empty() ? nullptr : manifolds[b];
  };
  for (size_t b = 0; b < nb; ++b) {
    const ceres::Manifold* m = manifoldOf(b);
    if (m != nullptr && m->AmbientSize() != sizes[b]) {
      result.problem = "manifold of block " + std::to_string(b) + " has ambient size " +
                       std::to_string(m->AmbientSize()) + ", the block has " + std::to_string(sizes[b]);
      return result;
    }
  }

  // Private copies: the caller's parameters stay untouched.
  std::vector<Eigen::VectorXd> x(nb);
  std::vector<const double*> ptrs(nb);
  for (size_t b = 0; b < nb; ++b) {
    x[b] = Eigen::Map<const Eigen::VectorXd>(params[b], sizes[b]);
    ptrs[b] = x[b].data();
  }

  // 1. Analytic, all Jacobians requested.
  const Evaluation full = evaluate(f, ptrs, std::vector<bool>(nb, true));
  result.evaluated = full.ok;
  if (!full.ok) {
    result.problem = "Evaluate() returned false at the given parameters";
    return result;
  }
  result.residuals = full.residuals;

  // 1b. The tangent-space path, if the factor has one: pose blocks are the 7-double blocks on a 6-D manifold.
  const auto* tangent_path = dynamic_cast<const TangentJacobians*>(&f);
  std::vector<bool> pose(nb, false);
  for (size_t b = 0; b < nb; ++b)
    pose[b] = sizes[b] == 7 && manifoldOf(b) != nullptr && manifoldOf(b)->TangentSize() == 6;
  Evaluation in_tangent;
  if (tangent_path != nullptr) {
    in_tangent = evaluate(f, ptrs, std::vector<bool>(nb, true), tangent_path, pose);
    if (!in_tangent.ok || !sameNumbers(in_tangent.residuals, full.residuals)) {
      result.evaluated = false;
      result.problem = "evaluateTangentSpace() failed or its residuals differ from Evaluate()'s";
      return result;
    }
  }

  // 2. Consistency: no Jacobians, then every block's Jacobian left out in turn.
  result.residuals_consistent = true;
  const Evaluation none = evaluate(f, ptrs, std::vector<bool>(nb, false));
  if (!none.ok || !sameNumbers(none.residuals, full.residuals)) {
    result.residuals_consistent = false;
    result.problem = "residuals differ (or Evaluate failed) when no Jacobians are requested";
  }
  for (size_t skip = 0; skip < nb && result.residuals_consistent; ++skip) {
    std::vector<bool> want(nb, true);
    want[skip] = false;
    const Evaluation partial = evaluate(f, ptrs, want);
    bool same = partial.ok && sameNumbers(partial.residuals, full.residuals);
    for (size_t b = 0; b < nb && same; ++b)
      if (b != skip && full.jacobians[b].allFinite())
        same = sameNumbers(partial.jacobians[b], full.jacobians[b]);
    if (!same) {
      result.residuals_consistent = false;
      result.problem = "residuals or Jacobians change when the Jacobian of block " + std::to_string(skip) +
                       " is not requested (Ceres does that for constant blocks)";
    }
  }

  // 3. Per block: analytic tangent Jacobian vs central differences through Plus.
  for (size_t b = 0; b < nb; ++b) {
    const ceres::Manifold* m = manifoldOf(b);
    const int ambient = sizes[b];
    const int tangent = m != nullptr ? m->TangentSize() : ambient;
    BlockJacobianError err;
    err.block = static_cast<int>(b);
    err.ambient_size = ambient;
    err.tangent_size = tangent;

    Eigen::MatrixXd plus_jac = Eigen::MatrixXd::Identity(ambient, tangent);
    if (m != nullptr) {
      RowMajorMatrix pj(ambient, tangent);
      if (!m->PlusJacobian(x[b].data(), pj.data())) {
        result.evaluated = false;
        result.problem = "PlusJacobian() failed for block " + std::to_string(b);
        return result;
      }
      plus_jac = pj;
    }
    const Eigen::MatrixXd J_ambient = full.jacobians[b];
    err.finite = J_ambient.allFinite();
    err.analytic = J_ambient * plus_jac;
    if (tangent_path != nullptr) {
      const Eigen::MatrixXd J_given = in_tangent.jacobians[b];
      err.finite = err.finite && J_given.allFinite();
      err.tangent_space = pose[b] ? J_given : Eigen::MatrixXd(J_given * plus_jac);
    }

    err.numeric = Eigen::MatrixXd::Zero(rows, tangent);
    const Eigen::VectorXd x0 = x[b];
    Eigen::VectorXd shifted(ambient);
    for (int k = 0; k < tangent; ++k) {
      Eigen::VectorXd r_pm[2];
      for (int s = 0; s < 2; ++s) {
        Eigen::VectorXd delta = Eigen::VectorXd::Zero(tangent);
        delta[k] = s == 0 ? step : -step;
        if (m != nullptr) {
          if (!m->Plus(x0.data(), delta.data(), shifted.data())) {
            result.evaluated = false;
            result.problem = "Plus() failed for block " + std::to_string(b);
            return result;
          }
        } else {
          shifted = x0 + delta;
        }
        x[b] = shifted;
        ptrs[b] = x[b].data();
        const Evaluation e = evaluate(f, ptrs, std::vector<bool>(nb, false));
        if (!e.ok) {
          result.evaluated = false;
          result.problem = "Evaluate() failed at a perturbed value of block " + std::to_string(b);
          x[b] = x0;
          return result;
        }
        r_pm[s] = e.residuals;
      }
      err.numeric.col(k) = (r_pm[0] - r_pm[1]) / (2.0 * step);
    }
    x[b] = x0;
    ptrs[b] = x[b].data();

    for (int i = 0; i < rows; ++i) {
      for (int k = 0; k < tangent; ++k) {
        // The worse of the two analytic paths.
        double a = err.analytic(i, k);
        const double n = err.numeric(i, k);
        if (err.tangent_space.size() != 0 && std::abs(err.tangent_space(i, k) - n) > std::abs(a - n))
          a = err.tangent_space(i, k);
        const double abs_err = std::abs(a - n);
        const double rel_err = abs_err / std::max({1.0, std::abs(a), std::abs(n)});
        err.max_abs_error = std::max(err.max_abs_error, abs_err);
        if (rel_err > err.max_rel_error || (err.worst_row < 0 && !std::isfinite(rel_err))) {
          err.max_rel_error = std::isfinite(rel_err) ? rel_err : std::numeric_limits<double>::infinity();
          err.worst_row = i;
          err.worst_col = k;
        }
      }
    }
    if (!err.finite) err.max_rel_error = std::numeric_limits<double>::infinity();
    result.blocks.push_back(std::move(err));
  }
  return result;
}

::testing::AssertionResult jacobiansMatch(const ceres::CostFunction& f, const std::vector<double*>& params,
                                          const std::vector<const ceres::Manifold*>& manifolds, double tol,
                                          double step) {
  const JacobianCheckResult r = checkJacobians(f, params, manifolds, step);
  if (r.ok(tol)) return ::testing::AssertionSuccess() << r.describe(tol);
  return ::testing::AssertionFailure() << "Jacobian check failed (tol " << tol << ", step " << step << "):\n"
                                       << r.describe(tol, true);
}

}  // namespace linnet::testing
