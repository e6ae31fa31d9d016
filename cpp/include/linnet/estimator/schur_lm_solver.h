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

#include <unordered_map>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <Eigen/Core>

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
  double min_diagonal = 1e-6;             // clamp of diag(J^T J) in the damping
  double max_diagonal = 1e32;
};

struct SchurLmSummary {
  double initial_cost = 0.0;  // 0.5 * sum of robustified squared residuals
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
  /// Adds a residual over registered blocks (in the cost function's order). `loss` may be nullptr.
  void addResidual(const ceres::CostFunction* cost, const ceres::LossFunction* loss, const std::vector<double*>& blocks);

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
    int offset;  // kept blocks: offset in the reduced system; eliminated blocks: index into landmarks_
  };
  struct Residual {
    const ceres::CostFunction* cost;
    const ceres::LossFunction* loss;
    std::vector<int> blocks;  // indices into blocks_
    int rows;
    int landmark = -1;        // index into landmarks_ of its eliminated block, -1 if none
    std::vector<int> slots;   // per block: its index in that landmark's `kept` list (-1: eliminated / no landmark)
    std::size_t arena = 0;    // offset of its scratch in arena_: r (rows), then per block J ambient and J tangent
  };
  // One eliminated block's normal-equation pieces.
  struct Landmark {
    int block;                          // index into blocks_
    int size;                           // tangent size e
    int offset;                         // offset in the stacked eliminated vectors (g_e_, D_e_, dx)
    Eigen::MatrixXd H_ee;               // e x e
    std::vector<int> kept;              // kept blocks it shares residuals with (indices into blocks_)
    std::vector<Eigen::MatrixXd> H_ek;  // e x tangent(kept[i])
  };
  void prepare();
  /// Residuals, robustified, with tangent Jacobians when `linearise`: fills H_, g_ and the landmarks' pieces.
  double evaluate(bool linearise);
  /// Solves the damped system for the step; false if the reduced system is not positive definite.
  bool computeStep(double mu, Eigen::VectorXd* dx_kept, Eigen::VectorXd* dx_elim, double* model_decrease);
  void applyStep(const Eigen::VectorXd& dx_kept, const Eigen::VectorXd& dx_elim);
  void saveValues();
  void restoreValues();

  std::vector<Block> blocks_;
  std::unordered_map<const double*, int> index_;
  std::vector<Residual> residuals_;
  std::vector<Landmark> landmarks_;
  int reduced_size_ = 0;
  int eliminated_size_ = 0;
  bool prepared_ = false;

  Eigen::MatrixXd H_;  // reduced-size dense J^T J of the kept blocks (upper and lower filled)
  Eigen::VectorXd g_;  // J^T r of the kept blocks
  Eigen::VectorXd g_e_;  // J^T r of the eliminated blocks, stacked
  std::vector<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> plus_jacobians_;
  std::vector<double> arena_;  // per-residual scratch (residual and Jacobians), allocated once per problem
  std::vector<double*> param_ptrs_;  // scratch for CostFunction::Evaluate
  SchurLmOptions options_;
  std::vector<double> saved_;
};

}  // namespace linnet
