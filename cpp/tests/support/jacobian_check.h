// The one Jacobian checker every factor test calls (DESIGN A5).
//
// checkJacobians() evaluates a ceres::CostFunction's analytic Jacobians, maps each block to its tangent space
// (J_ambient * PlusJacobian(x), the product Ceres itself forms), and compares them with central differences
// taken through Manifold::Plus (x + h e_k for Euclidean blocks):
//     numeric(:, k) = (r(Plus(x, h e_k)) - r(Plus(x, -h e_k))) / (2 h).
// It also checks that the residuals do not depend on which Jacobians were requested (all, none, or all but
// one block: Ceres passes nullptr for constant blocks) and that every requested Jacobian entry was written
// (the buffers are pre-filled with NaN).
//
// A cost function that also implements linnet::TangentJacobians (the solver's tangent-space path) is checked
// twice: its evaluateTangentSpace() Jacobians (pose blocks as they are, other blocks times PlusJacobian) are compared
// with the same numeric ones, and its residuals with Evaluate's; a block's errors are the worse of the two.
//
// Error measures per block: max_abs_error = max |a - n| over entries; max_rel_error = max |a - n| / max(1,
// |a|, |n|) over entries (relative for large entries, absolute for entries below 1, which suits whitened
// residuals).
//
//   EXPECT_TRUE(linnet::testing::jacobiansMatch(factor, {pose_i, sb_i}, {&pose_manifold, nullptr}, 1e-6));
#pragma once

#include <string>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/manifold.h>
#include <gtest/gtest.h>

#include <Eigen/Core>

namespace linnet::testing {

struct BlockJacobianError {
  int block = 0;               // parameter block index
  int ambient_size = 0;        // block size as Ceres sees it
  int tangent_size = 0;        // columns of the compared Jacobians
  double max_abs_error = 0.0;  // max |analytic - numeric|
  double max_rel_error = 0.0;  // max |analytic - numeric| / max(1, |analytic|, |numeric|)
  int worst_row = -1;          // entry with the largest relative error
  int worst_col = -1;
  bool finite = true;        // every analytic entry written and finite
  Eigen::MatrixXd analytic;  // residuals x tangent (J_ambient * PlusJacobian)
  Eigen::MatrixXd numeric;   // residuals x tangent (central differences through Plus)
  Eigen::MatrixXd tangent_space;  // residuals x tangent from evaluateTangentSpace (empty if not implemented)
};

struct JacobianCheckResult {
  bool evaluated = false;             // every Evaluate / Plus / PlusJacobian call returned true
  bool residuals_consistent = false;  // residuals and Jacobians independent of which Jacobians were requested
  std::string problem;                // first structural problem found (empty if none)
  Eigen::VectorXd residuals;          // at the given parameters
  std::vector<BlockJacobianError> blocks;

  double maxAbsError() const;
  double maxRelError() const;
  /// evaluated, consistent, all entries finite and every block's max_rel_error <= tol.
  bool ok(double tol) const;
  /// One line per block (and the structural problem, if any); with `matrices`, the analytic and numeric
  /// Jacobians of blocks whose relative error exceeds `tol`.
  std::string describe(double tol = 0.0, bool matrices = false) const;
};

/// Compares analytic and numeric Jacobians. `manifolds` is empty (all Euclidean) or has one entry per
/// parameter block, nullptr meaning Euclidean. `params` are not modified. `step` is the tangent step h.
JacobianCheckResult checkJacobians(const ceres::CostFunction& f, const std::vector<double*>& params,
                                   const std::vector<const ceres::Manifold*>& manifolds, double step = 1e-6);

/// For EXPECT_TRUE: success iff checkJacobians(...).ok(tol); the failure message holds describe(tol, true).
::testing::AssertionResult jacobiansMatch(const ceres::CostFunction& f, const std::vector<double*>& params,
                                          const std::vector<const ceres::Manifold*>& manifolds, double tol,
                                          double step = 1e-6);

}  // namespace linnet::testing
