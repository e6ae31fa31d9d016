// A Levenberg-Marquardt solver for sliding-window problems, with the landmark blocks eliminated by the Schur
// complement (Triggs et al., "Bundle Adjustment - A Modern Synthesis", 2000, sec. 6.1; the LM radius update of
// Nielsen, 1999, as in Ceres).
//
// It solves the same problems the window builds for Ceres (ceres::CostFunction residuals, ceres::LossFunction
// robustifiers, ceres::Manifold blocks) but is specialised for their shape: a few dozen frame states kept in one
// dense reduced system, and many small landmark blocks (inverse depth: 1-D) each touching a few frames. Ceres' generic
// Schur eliminator has no fixed-size path for 1-D landmark blocks and locks a mutex per block update; on the
// per-frame window solve this solver needs about a fifth of its instructions for the same result.
#pragma once

#include <initializer_list>
#include <span>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <Eigen/Cholesky>
#include <Eigen/Core>

#include "linnet/estimator/block_index.h"
#include "linnet/estimator/factors/tangent_jacobians.h"

namespace linnet {

struct SchurLmOptions {
  int max_iterations = 3;                 // LM iterations (each solves one linear system)
  double max_time_s = 1e9;                // no new iteration starts after this much wall time, s (when it binds,
                                          // results depend on the machine's speed)
  double initial_radius = 1e8;            // trust-region radius; the damping is 1 / radius times diag(J^T J). Large:
                                          // the first step is nearly Gauss-Newton (window problems are well posed
                                          // thanks to their priors); with Ceres' 1e4 the damping slowed the
                                          // convergence along weak directions (3 iterations: synthetic APE 8.5 vs
                                          // 5.4 mm)
  double min_relative_decrease = 1e-3;    // a step is accepted when the cost falls by at least this share of the
                                          // decrease the linear model predicts
  double function_tolerance = 1e-6;       // stop when the relative cost change of a step is below this
  double landmark_damping = 1e3;          // absolute Levenberg term added to the diagonal of multi-dimensional eliminated
                                          // blocks (lines, 4-DoF), whitened cost per tangent unit^2: bounds the step of a
                                          // line along a nearly unobservable direction (undamped, such a step diverged on
                                          // the V1_02 room replay, APE 1.21 m). A trade-off: 10 gave V1_02 room / lowtex
                                          // 0.0108 / 0.032 m (1e3: 0.0121 / 0.034) but MH_01 hall 0.022 m (1e3: 0.0148,
                                          // points only 0.0173). Not applied when the same blocks are not eliminated
  int landmark_iterations = 0;            // Gauss-Newton iterations of each multi-dimensional eliminated block alone
                                          // (lines; the kept blocks held) before the first joint step and after every
                                          // accepted one ("embedded point iterations", Jeong et al., CVPR 2010). The
                                          // joint step moves a line only partly (landmark_damping); these let the
                                          // lines catch up with the poses, so that the next joint step is taken from
                                          // converged lines. 0: none
  double min_diagonal = 1e-6;             // clamp of diag(J^T J) in the damping
  double max_diagonal = 1e32;
};

struct SchurLmSummary {
  double initial_cost = 0.0;  // 0.5 * sum of robustified squared residuals (after the landmark_iterations, if any)
  double final_cost = 0.0;
  int iterations = 0;         // linear systems solved
  int successful_steps = 0;
  int jacobian_evaluations = 0;
  bool converged = false;     // stopped by function_tolerance (not by the iteration bound)
};

class SchurLmSolver {
 public:
  /// Registers a parameter block: `ambient_size` doubles at `data`, updated through `manifold` (nullptr: Euclidean).
  /// `eliminate`: a landmark block, removed by the Schur complement (it may only share residuals with kept blocks,
  /// never with another eliminated block). The pointers must stay valid until solve() returns.
  void addParameterBlock(double* data, int ambient_size, const ceres::Manifold* manifold, bool eliminate);
  /// Registers a block that the residuals read but the solve leaves as it is (Ceres' SetParameterBlockConstant): no
  /// Jacobian is asked for it and it has no rows in the system.
  void addConstantBlock(double* data, int ambient_size);
  /// True if the block at `data` is registered (as a parameter or a constant block).
  bool hasBlock(const double* data) const { return index_.find(data) >= 0; }
  /// Adds a residual over registered blocks (in the cost function's order). `loss` may be nullptr.
  void addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss, std::span<double* const> blocks);
  void addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss,
                   std::initializer_list<double*> blocks) {
    addResidual(cost, loss, std::span<double* const>(blocks.begin(), blocks.size()));
  }

  /// Minimises the cost, starting from the values in the blocks, and leaves the result there. Throws UsageError for a
  /// malformed problem (unknown block, a residual between two eliminated blocks, wrong block sizes).
  SchurLmSummary solve(const SchurLmOptions& options);

  /// Total cost 0.5 * sum rho(|r|^2) at the blocks' current values.
  double cost();

 private:
  struct Block {
    double* data;
    int ambient;
    int tangent;
    const ceres::Manifold* manifold;
    bool eliminate;
    bool pose = false;  // a pose block (7, PoseManifold): TangentJacobians factors give its tangent Jacobian
    bool constant = false;  // read only (addConstantBlock)
    int offset;  // kept blocks: offset in the reduced system; eliminated blocks: index into landmarks_; constant: -1
  };
  struct Residual {
    const ceres::CostFunction* cost;
    const ceres::LossFunction* loss;
    const TangentJacobians* tangent;  // cost, when it gives pose Jacobians in the tangent space (else nullptr)
    int first;                // its blocks are res_blocks_[first, first + count) (indices into blocks_)
    int count;
    int rows;
    int landmark = -1;        // index into landmarks_ of its eliminated block, -1 if none
    int landmark_pos = -1;    // position of that block among the residual's blocks
    std::size_t arena = 0;    // offset of its scratch in arena_: r (rows), then per block J ambient and J tangent
  };
  // One eliminated block's normal-equation pieces. Its kept blocks and matrices live in flat arrays (kept_,
  // hek_offset_, lm_data_), so that a solve allocates per problem, not per landmark.
  struct Landmark {
    int block;              // index into blocks_
    int size;               // tangent size e
    int offset;             // offset in the stacked eliminated vectors (g_e_, D_e, dx)
    int kept_first = 0;     // its kept blocks (those it shares residuals with): kept_[kept_first, + kept_count)
    int kept_count = 0;
    std::size_t hee = 0;    // H_ee (e x e, column-major) at lm_data_[hee]
    std::size_t inv = 0;    // the damped H_ee^-1 of a multi-dimensional landmark at inv_data_[inv]
    int res_first = 0;      // its residuals: lm_residuals_[res_first, + res_count) (indices into residuals_)
    int res_count = 0;
  };
  using MatMap = Eigen::Map<Eigen::MatrixXd, Eigen::Aligned16>;
  MatMap Hee(const Landmark& lm) { return MatMap(lm_data_.data() + lm.hee, lm.size, lm.size); }
  // H_ek of the landmark's i-th kept block: e x tangent(kept), column-major.
  MatMap Hek(const Landmark& lm, int i) {
    const int k = lm.kept_first + i;
    return MatMap(lm_data_.data() + hek_offset_[static_cast<std::size_t>(k)], lm.size,
                  blocks_[static_cast<std::size_t>(kept_[static_cast<std::size_t>(k)])].tangent);
  }
  int keptBlock(const Landmark& lm, int i) const { return kept_[static_cast<std::size_t>(lm.kept_first + i)]; }
  void prepare();
  /// Residuals, robustified, with tangent Jacobians when `linearise`: fills H_, g_ and the landmarks' pieces.
  double evaluate(bool linearise);
  /// Solves the damped system for the step; false if the reduced system is not positive definite.
  bool computeStep(double mu, Eigen::VectorXd* dx_kept, Eigen::VectorXd* dx_elim, double* model_decrease);
  void applyStep(const Eigen::VectorXd& dx_kept, const Eigen::VectorXd& dx_elim);
  /// One block moved by a tangent step (its manifold's Plus, or added).
  void plusBlock(const Block& b, const double* delta);
  /// options_.landmark_iterations damped Gauss-Newton steps of every multi-dimensional landmark alone, each kept only
  /// if it lowers that landmark's robust cost.
  void refineLandmarks();
  /// Robust cost of one landmark's residuals; with `H`, `g` (tangent size) also their IRLS normal equations.
  double landmarkCost(const Landmark& lm, Eigen::MatrixXd* H, Eigen::VectorXd* g);
  void saveValues();
  void restoreValues();

  std::vector<Block> blocks_;
  BlockIndex index_;
  TangentJacobiansCache tangent_of_;  // the residuals' TangentJacobians, looked up once per cost function type
  std::vector<Residual> residuals_;
  std::vector<int> res_blocks_;  // the residuals' blocks, flat
  std::vector<int> res_slots_;   // parallel: the block's index in its residual's landmark's kept list (-1: none)
  std::vector<Landmark> landmarks_;
  std::vector<int> lm_residuals_;         // the landmarks' residuals, flat (Landmark::res_first / res_count)
  std::vector<int> kept_;                 // the landmarks' kept blocks, flat (with slack)
  std::vector<std::size_t> hek_offset_;   // parallel to kept_: offset of that H_ek in lm_data_
  Eigen::VectorXd lm_data_;               // every landmark's H_ee and H_ek, 16-byte aligned pieces
  Eigen::VectorXd inv_data_;              // damped H_ee^-1 of the multi-dimensional landmarks (computeStep)
  int reduced_size_ = 0;
  int eliminated_size_ = 0;
  bool prepared_ = false;

  Eigen::MatrixXd H_;  // reduced-size dense J^T J of the kept blocks (upper and lower filled)
  Eigen::VectorXd g_;  // J^T r of the kept blocks
  Eigen::VectorXd g_e_;  // J^T r of the eliminated blocks, stacked
  std::vector<int> block_of_row_;  // per row of H_: offset of its kept block (set by prepare, used to symmetrise)
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> plus_jacobians_;
  std::vector<double> arena_;  // per-residual scratch (residual and Jacobians), allocated once per problem
  std::vector<double*> param_ptrs_, jacobian_ptrs_;  // scratch for CostFunction::Evaluate
  // computeStep scratch, kept between iterations (same sizes: no allocation after the first).
  Eigen::MatrixXd S_;
  Eigen::VectorXd rhs_, D_, D_e_, inv_scalar_, back_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  SchurLmOptions options_;
  std::vector<double> saved_, plus_out_;
  // refineLandmarks scratch, kept between landmarks (same sizes: no allocation after the first): one residual with
  // its landmark's ambient and tangent Jacobians, the landmark's values before a step, its normal equations, the
  // damped system and the step.
  std::vector<double> lm_scratch_, lm_saved_;
  Eigen::MatrixXd lm_H_, lm_A_;
  Eigen::VectorXd lm_g_, lm_delta_;
  Eigen::LLT<Eigen::MatrixXd> lm_llt_;
};

}  // namespace linnet
