// The prior left by marginalisation (DESIGN B1) and the Ceres cost function that applies it.
//
// A MarginalizationPrior is the linearisation, at x0, of everything that was eliminated:
//     cost(x) = 1/2 || r + J * (x [-] x0) ||^2
// where x [-] x0 stacks, block by block, the manifold difference Minus(x_k, x0_k) (plain x_k - x0_k for a
// Euclidean block). J^T J is the Schur complement H* and J^T r its gradient g* at x0 (Sibley et al., "Sliding
// window filter with application to planetary landing", JFR 2010; Leutenegger et al., "Keyframe-based
// visual-inertial odometry using nonlinear optimization", IJRR 2015).
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/manifold.h>
#include <Eigen/Core>

namespace linnet {

/// Caller-chosen identifier of a parameter block (e.g. a frame's stable id times a small factor plus a slot).
using BlockKey = std::int64_t;

/// The linearised prior over the kept blocks. Immutable once built; shared between PriorFactor and its
/// creator.
struct MarginalizationPrior {
  std::vector<BlockKey> keys;           // kept blocks, in the order of the PriorFactor's parameter blocks
  std::vector<int> ambient_sizes;       // per block: size of the parameter array
  std::vector<int> tangent_sizes;       // per block: size of its tangent space (columns of J)
  std::vector<int> tangent_offsets;     // per block: first column of the block in J
  std::vector<std::vector<double>> x0;  // per block: linearisation point (ambient values)
  std::vector<const ceres::Manifold*> manifolds;  // per block: manifold or nullptr (Euclidean); NOT owned:
                                                  // the caller's manifolds must outlive the prior
  Eigen::MatrixXd J;             // linearised square-root information: rank x total tangent size
  Eigen::VectorXd r;             // residual at x0: rank
  int dropped_tangent_size = 0;  // dimension that was eliminated (information only)

  int totalTangentSize() const { return static_cast<int>(J.cols()); }
  /// Index of `key` in `keys`, or -1.
  int indexOf(BlockKey key) const;
  /// 1/2 |r|^2: the prior's cost at x0.
  double costAtX0() const { return 0.5 * r.squaredNorm(); }
};

/// Cost function r + J * (x [-] x0) over the prior's blocks, in prior->keys order, with exact Jacobians: the
/// derivative of Minus(Plus(x, d), x0) with respect to d is analytic for Euclidean blocks (identity) and for
/// PoseManifold (blockdiag(I, Jr^-1(Log(q0^-1 q)))); other manifolds use a central difference of their own
/// Plus / Minus. The ambient Jacobian handed to Ceres is that times MinusJacobian(x).
class PriorFactor : public ceres::CostFunction {
 public:
  explicit PriorFactor(std::shared_ptr<const MarginalizationPrior> prior);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;

  const MarginalizationPrior& prior() const { return *prior_; }
  const std::shared_ptr<const MarginalizationPrior>& sharedPrior() const { return prior_; }

 private:
  std::shared_ptr<const MarginalizationPrior> prior_;
};

}  // namespace linnet
