// Schur-complement marginalisation (DESIGN B1): linearise the residuals that touch the blocks to drop,
// eliminate those blocks from H dx = -g, and return the result as a square-root prior (MarginalizationPrior)
// on the blocks they were connected to.
//
// Usage (one Marginaliser per marginalisation step):
//   Marginaliser m;
//   m.addParameterBlock(key, values, ambient_size, manifold_or_nullptr);  // every block a residual touches
//   m.addResidual(cost, loss, {key_a, key_b, ...});                       // every residual touching a dropped block
//   auto prior = m.marginalise({keys to drop});                           // -> PriorFactor(prior) in the next window
// A previous prior is re-marginalised by adding std::make_shared<PriorFactor>(old_prior) with keys
// old_prior->keys.
//
// Elimination runs in two stages that give the same Schur complement: first the dropped blocks that share no
// residual with one another (e.g. the inverse depths hosted by the dropped frame: H_PP is block-diagonal,
// inverted block by block), then the remaining dropped blocks through a dense eigen-decomposition
// (pseudo-inverse with the threshold). The result H* becomes the square root J with J^T J = H*: its Cholesky
// factor (J = L^T, r = L^-1 g*) when H* is certainly of full rank above the threshold, else J = sqrt(S) V^T,
// r = sqrt(S)^-1 V^T g* from H* = V S V^T over the eigenvalues above the threshold.
//
// Robust losses: each residual is corrected as Ceres' own trust-region solver does (Triggs et al., "Bundle
// adjustment - a modern synthesis", 2000, sec. 4.3): r' = sqrt(rho')/(1 - a) r, J' = sqrt(rho') (I - a r
// r^T/|r|^2) J with a = 1 - sqrt(1 + 2 |r|^2 rho''/rho'); when rho'' <= 0 (Huber, Cauchy, ...) this is the
// plain sqrt(rho') scaling of residual and Jacobian that VINS-Mono uses. So H and g match what the solver saw
// at its last step.
#pragma once

#include <initializer_list>
#include <map>
#include <memory>
#include <span>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>

#include "linnet/estimator/factors/prior_factor.h"
#include "linnet/estimator/factors/tangent_jacobians.h"

namespace linnet {

struct MarginaliserOptions {
  // Eigenvalues of H_mm and of the Schur complement at or below max(eigenvalue_threshold,
  // relative_eigenvalue_threshold * largest eigenvalue of that matrix) count as zero: H_mm is pseudo-inverted
  // and the prior keeps only the directions above the threshold. The relative part removes round-off-level
  // directions (condition numbers past ~1e13 carry no information in double precision).
  double eigenvalue_threshold = 1e-8;            // information units (1 / tangent unit^2)
  double relative_eigenvalue_threshold = 1e-13;  // dimensionless

  template <class V>
  void visit(V& v) {
    v("eigenvalue_threshold", eigenvalue_threshold, "eigenvalues below this count as zero", 0.0, 1e3);
    v("relative_eigenvalue_threshold", relative_eigenvalue_threshold,
      "eigenvalues below this times the largest count as zero", 0.0, 1e-3);
  }
};

/// Statistics of the last marginalise() call, for logs and tests.
struct MarginalisationStats {
  int residuals_used = 0;           // residuals touching a dropped block
  int dropped_size = 0;             // tangent dimension eliminated
  int kept_size = 0;                // tangent dimension of the prior's blocks
  int prior_rank = 0;               // rows of the prior's J
  int dropped_rank_deficiency = 0;  // eigenvalues of H_mm below the threshold
  int decoupled_blocks = 0;         // dropped blocks eliminated in the cheap block-diagonal first stage
};

class Marginaliser {
 public:
  explicit Marginaliser(MarginaliserOptions options = {});
  // Residuals point at their blocks' map nodes: a copy's would point into the original. Moving keeps the nodes.
  Marginaliser(const Marginaliser&) = delete;
  Marginaliser& operator=(const Marginaliser&) = delete;
  Marginaliser(Marginaliser&&) = default;
  Marginaliser& operator=(Marginaliser&&) = default;

  /// Registers a parameter block. `values` (ambient_size doubles) is COPIED now: the linearisation point is
  /// the value at registration. `manifold` (nullptr = Euclidean) is not owned and must outlive the returned
  /// prior. Throws UsageError on a duplicate key or inconsistent sizes.
  void addParameterBlock(BlockKey key, const double* values, int ambient_size,
                         const ceres::Manifold* manifold);

  /// True if a block with this key is registered.
  bool hasParameterBlock(BlockKey key) const { return blocks_.count(key) != 0; }

  /// Declares a block as held constant: its columns are not estimated, it never enters a prior.
  void setParameterBlockConstant(BlockKey key);

  /// Adds a residual over registered blocks (in the cost function's parameter order). `loss` (may be nullptr)
  /// is not owned and must stay alive until marginalise() returns. Throws UsageError on an unknown key or a
  /// size mismatch.
  void addResidual(std::shared_ptr<ceres::CostFunction> cost, ceres::LossFunction* loss,
                   std::span<const BlockKey> keys);
  void addResidual(std::shared_ptr<ceres::CostFunction> cost, ceres::LossFunction* loss,
                   std::initializer_list<BlockKey> keys) {
    addResidual(std::move(cost), loss, std::span<const BlockKey>(keys.begin(), keys.size()));
  }

  /// Linearises every residual that touches a block of `drop` at the registered values, eliminates `drop` and
  /// returns the prior over every other non-constant block those residuals touch (in registration order).
  /// Returns nullptr if no residual touches a dropped block or the prior would have rank 0. Throws UsageError
  /// for an unregistered key, InputError if a cost function fails to evaluate or returns non-finite values.
  std::shared_ptr<const MarginalizationPrior> marginalise(const std::vector<BlockKey>& drop);

  const MarginalisationStats& lastStats() const { return stats_; }
  int numParameterBlocks() const { return static_cast<int>(blocks_.size()); }
  int numResiduals() const { return static_cast<int>(residuals_.size()); }

 private:
  struct Block {
    std::vector<double> values;
    int ambient_size = 0;
    int tangent_size = 0;
    const ceres::Manifold* manifold = nullptr;
    int order = 0;  // registration order
    bool constant = false;
    bool pose = false;  // 7 values on PoseManifold: a TangentJacobians factor gives its Jacobian in the tangent space
    // Set by marginalise() for its own use: the block's index in the dropped list (-1: kept) and its first column in
    // the joint system (-1: not in it).
    int drop_index = -1;
    int offset = -1;
    bool dense = false;  // reached by a residual of other than two rows (IMU, prior): see marginalise()
  };
  struct Residual {
    std::shared_ptr<ceres::CostFunction> cost;
    ceres::LossFunction* loss = nullptr;
    std::size_t first = 0;                      // its keys and blocks: key_store_ / block_store_ [first, + count)
    std::size_t count = 0;                      // (two heap vectors per residual cost more than its evaluation)
    const TangentJacobians* tangent = nullptr;  // cost, when it gives tangent-space Jacobians
  };
  std::span<const BlockKey> keysOf(const Residual& res) const {
    return std::span<const BlockKey>(key_store_).subspan(res.first, res.count);
  }
  /// The keys' blocks (a std::map's nodes, which do not move).
  std::span<Block* const> blocksOf(const Residual& res) const {
    return std::span<Block* const>(block_store_).subspan(res.first, res.count);
  }

  /// `dropped` reordered so that the first *num_decoupled blocks share no residual (block-diagonal H_PP).
  std::vector<BlockKey> orderForElimination(const std::vector<BlockKey>& dropped,
                                            const std::vector<const Residual*>& used,
                                            int* num_decoupled) const;

  MarginaliserOptions options_;
  std::map<BlockKey, Block> blocks_;
  std::vector<Residual> residuals_;
  std::vector<BlockKey> key_store_;  // every residual's keys, in order
  std::vector<Block*> block_store_;  // and their blocks
  TangentJacobiansCache tangent_of_;  // the residuals' TangentJacobians, looked up once per cost function type
  MarginalisationStats stats_;
};

}  // namespace linnet
