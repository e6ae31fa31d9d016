// SchurLmSolver against Ceres on a small window problem: poses on the pose manifold, inverse-depth landmarks
// (eliminated), point reprojection residuals with a Huber loss and a few gross outliers, pose priors for the gauge.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>

#include "linnet/core/error.h"
#include "linnet/estimator/factors/point_factors.h"
#include "estimator/pose_prior_cost.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/schur_lm_solver.h"

namespace linnet {
namespace {

using testing::PosePrior;

struct Problem {
  std::vector<std::array<double, 7>> poses;
  std::vector<double> inv_depth;
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  struct Res {
    ceres::CostFunction* cost;
    bool robust;
    std::vector<int> pose_idx;  // poses used, in order
    int landmark;               // -1: none (last block)
  };
  std::vector<Res> res;
};

// Five body poses along a line looking at landmarks 2-6 m ahead; landmarks hosted in pose k % 2 and seen by every
// other pose; `outliers` observations moved by 30 px.
Problem makeProblem(unsigned seed, int outliers) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  const Pose T_B_C(Quat::Identity(), Vec3::Zero());
  std::vector<Pose> truth;
  for (int i = 0; i < 5; ++i)
    truth.emplace_back(Quat(Eigen::AngleAxisd(0.05 * i, Vec3::UnitY())), Vec3(0.3 * i, 0.05 * U(rng), 0.0));
  Problem p;
  for (const Pose& T : truth) {
    // Start away from the truth.
    const Pose T0(T.q * expSO3(Vec3(0.02 * U(rng), 0.02 * U(rng), 0.02 * U(rng))),
                  T.p + Vec3(0.05 * U(rng), 0.05 * U(rng), 0.05 * U(rng)));
    std::array<double, 7> b{};
    setPose(T0, b.data());
    p.poses.push_back(b);
  }
  const double sqrt_info = 460.0 / 1.5;
  int outliers_left = outliers;
  for (int l = 0; l < 40; ++l) {
    const int host = l % 2;
    const Vec3 p_C(0.8 * U(rng), 0.6 * U(rng), 4.0 + 2.0 * U(rng));
    const Vec3 p_W = truth[host] * (T_B_C * p_C);
    p.inv_depth.push_back((1.0 / p_C.z()) * (1.0 + 0.1 * U(rng)));
    const Vec2 uv_host = p_C.head<2>() / p_C.z();
    for (int j = 0; j < 5; ++j) {
      if (j == host) continue;
      const Vec3 q = (truth[j] * T_B_C).inverse() * p_W;
      Vec2 uv = q.head<2>() / q.z();
      if (outliers_left > 0 && l % 7 == 3) {
        uv += Vec2(30.0 / 460.0, -30.0 / 460.0);
        --outliers_left;
      }
      p.costs.push_back(std::make_unique<PointReprojectionFactor>(uv_host, uv, T_B_C, T_B_C, sqrt_info));
      p.res.push_back({p.costs.back().get(), true, {host, j}, l});
    }
  }
  for (int i = 0; i < 2; ++i) {
    p.costs.push_back(
        std::make_unique<ceres::AutoDiffCostFunction<PosePrior, 6, 7>>(new PosePrior(truth[i], 1000.0)));
    p.res.push_back({p.costs.back().get(), false, {i}, -1});
  }
  return p;
}

std::vector<double*> blocksOf(Problem& p, const Problem::Res& r) {
  std::vector<double*> b;
  for (int i : r.pose_idx) b.push_back(p.poses[static_cast<std::size_t>(i)].data());
  if (r.landmark >= 0) b.push_back(&p.inv_depth[static_cast<std::size_t>(r.landmark)]);
  return b;
}

// Ceres' LM with its dense Schur solver; `iterations` at most, converged tightly when there are enough.
ceres::Solver::Summary solveCeres(Problem& p, const ceres::LossFunction* huber, const PoseManifold* manifold,
                                  int iterations, int constant_pose = -1) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (auto& b : p.poses) problem.AddParameterBlock(b.data(), 7, const_cast<PoseManifold*>(manifold));
  for (const auto& r : p.res)
    problem.AddResidualBlock(r.cost, r.robust ? const_cast<ceres::LossFunction*>(huber) : nullptr, blocksOf(p, r));
  if (constant_pose >= 0) problem.SetParameterBlockConstant(p.poses[static_cast<std::size_t>(constant_pose)].data());
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_SCHUR;
  o.max_num_iterations = iterations;
  o.function_tolerance = o.gradient_tolerance = o.parameter_tolerance = 1e-14;
  ceres::Solver::Summary s;
  ceres::Solve(o, &problem, &s);
  return s;
}

SchurLmSummary solveSchurLm(Problem& p, const ceres::LossFunction* huber, const PoseManifold* manifold,
                            bool eliminate, int iterations, int constant_pose = -1) {
  SchurLmSolver solver;
  for (std::size_t i = 0; i < p.poses.size(); ++i) {
    if (static_cast<int>(i) == constant_pose)
      solver.addConstantBlock(p.poses[i].data(), 7);
    else
      solver.addParameterBlock(p.poses[i].data(), 7, manifold, false);
  }
  for (double& d : p.inv_depth) solver.addParameterBlock(&d, 1, nullptr, eliminate);
  for (const auto& r : p.res) solver.addResidual(r.cost, r.robust ? huber : nullptr, blocksOf(p, r));
  SchurLmOptions o;
  o.max_iterations = iterations;
  o.function_tolerance = 1e-14;
  return solver.solve(o);
}

double maxDifference(const Problem& a, const Problem& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.poses.size(); ++i) {
    const Pose Ta = poseFromBlock(a.poses[i].data()), Tb = poseFromBlock(b.poses[i].data());
    d = std::max(d, (Ta.p - Tb.p).norm());
    d = std::max(d, logSO3(Ta.q.conjugate() * Tb.q).norm());
  }
  for (std::size_t l = 0; l < a.inv_depth.size(); ++l) d = std::max(d, std::abs(a.inv_depth[l] - b.inv_depth[l]));
  return d;
}

TEST(SchurLmSolver, ReachesCeresMinimum) {
  const ceres::HuberLoss huber(1.0);
  const PoseManifold manifold;
  for (const int outliers : {0, 4}) {
    Problem a = makeProblem(7, outliers), b = makeProblem(7, outliers);
    EXPECT_TRUE(solveCeres(a, &huber, &manifold, 100).IsSolutionUsable());
    const SchurLmSummary s = solveSchurLm(b, &huber, &manifold, true, 100);
    EXPECT_LT(s.final_cost, s.initial_cost);
    EXPECT_GT(s.successful_steps, 0);
    EXPECT_LT(maxDifference(a, b), 1e-7) << "outliers " << outliers;
  }
}

TEST(SchurLmSolver, EliminationGivesTheSameSteps) {
  // With the landmarks kept in the dense system instead of eliminated, every step (hence the result after a fixed
  // number of iterations) must be the same up to rounding: the Schur complement is exact.
  const ceres::HuberLoss huber(1.0);
  const PoseManifold manifold;
  Problem a = makeProblem(11, 3), b = makeProblem(11, 3);
  const SchurLmSummary sa = solveSchurLm(a, &huber, &manifold, true, 3);
  const SchurLmSummary sb = solveSchurLm(b, &huber, &manifold, false, 3);
  EXPECT_EQ(sa.successful_steps, sb.successful_steps);
  EXPECT_NEAR(sa.final_cost, sb.final_cost, 1e-9 * sa.initial_cost);
  EXPECT_LT(maxDifference(a, b), 1e-9);
}

TEST(SchurLmSolver, ConstantBlocksReachCeresMinimumWithTheBlockHeld) {
  // A pose held constant (as the calibration blocks are on non-keyframe solves): the same minimum as Ceres with
  // SetParameterBlockConstant, and the held block's values untouched, bit for bit.
  const ceres::HuberLoss huber(1.0);
  const PoseManifold manifold;
  for (const bool eliminate : {true, false}) {
    Problem a = makeProblem(13, 2), b = makeProblem(13, 2);
    const std::array<double, 7> held = b.poses[3];
    EXPECT_TRUE(solveCeres(a, &huber, &manifold, 100, 3).IsSolutionUsable());
    const SchurLmSummary s = solveSchurLm(b, &huber, &manifold, eliminate, 100, 3);
    EXPECT_LT(s.final_cost, s.initial_cost);
    EXPECT_EQ(b.poses[3], held);
    EXPECT_LT(maxDifference(a, b), 1e-7) << "eliminate " << eliminate;
    // Held, the minimum differs from the free one: the block really was constant.
    Problem c = makeProblem(13, 2);
    solveSchurLm(c, &huber, &manifold, eliminate, 100);
    EXPECT_GT(maxDifference(b, c), 1e-4);
  }
}

TEST(SchurLmSolver, FewIterationsDecreaseTheCostLikeCeres) {
  // The per-frame use: 3 iterations from a perturbed start. The cost must fall at least as far as Ceres' LM gets.
  const ceres::HuberLoss huber(1.0);
  const PoseManifold manifold;
  Problem a = makeProblem(5, 2);
  const SchurLmSummary s = solveSchurLm(a, &huber, &manifold, true, 3);
  Problem b = makeProblem(5, 2);
  const ceres::Solver::Summary cs = solveCeres(b, &huber, &manifold, 3);
  EXPECT_NEAR(s.initial_cost, cs.initial_cost, 1e-9 * cs.initial_cost);
  EXPECT_LE(s.final_cost, cs.final_cost * (1.0 + 1e-6));
}

TEST(SchurLmSolver, TimeBoundStopsBeforeTheFirstIteration) {
  const ceres::HuberLoss huber(1.0);
  const PoseManifold manifold;
  Problem p = makeProblem(7, 0);
  SchurLmSolver solver;
  for (auto& b : p.poses) solver.addParameterBlock(b.data(), 7, &manifold, false);
  for (double& d : p.inv_depth) solver.addParameterBlock(&d, 1, nullptr, true);
  for (const auto& r : p.res) solver.addResidual(r.cost, r.robust ? &huber : nullptr, blocksOf(p, r));
  SchurLmOptions o;
  o.max_iterations = 10;
  o.max_time_s = -1.0;  // already past
  const SchurLmSummary s = solver.solve(o);
  EXPECT_EQ(s.iterations, 0);
  EXPECT_EQ(s.final_cost, s.initial_cost);
}

TEST(SchurLmSolver, DegenerateProblemsSolveWithoutCrashing) {
  SchurLmOptions o;
  o.max_iterations = 5;
  {  // nothing at all
    SchurLmSolver solver;
    const SchurLmSummary s = solver.solve(o);
    EXPECT_EQ(s.final_cost, 0.0);
  }
  Problem p = makeProblem(5, 0);
  const PoseManifold manifold;
  {  // only eliminated blocks: every pose held
    SchurLmSolver solver;
    for (auto& pose : p.poses) solver.addConstantBlock(pose.data(), 7);
    for (double& d : p.inv_depth) solver.addParameterBlock(&d, 1, nullptr, true);
    for (const auto& r : p.res) solver.addResidual(r.cost, nullptr, blocksOf(p, r));
    const SchurLmSummary s = solver.solve(o);
    EXPECT_TRUE(std::isfinite(s.final_cost));
    EXPECT_LE(s.final_cost, s.initial_cost);
  }
  {  // a kept block with no residual
    SchurLmSolver solver;
    solver.addParameterBlock(p.poses[0].data(), 7, &manifold, false);
    const SchurLmSummary s = solver.solve(o);
    EXPECT_EQ(s.final_cost, 0.0);
  }
}

TEST(SchurLmSolver, MalformedProblemsThrow) {
  const PoseManifold manifold;
  Problem p = makeProblem(3, 0);
  SchurLmSolver solver;
  EXPECT_FALSE(solver.hasBlock(p.poses[0].data()));
  solver.addParameterBlock(p.poses[0].data(), 7, &manifold, false);
  solver.addConstantBlock(p.poses[2].data(), 7);
  EXPECT_TRUE(solver.hasBlock(p.poses[0].data()));
  EXPECT_TRUE(solver.hasBlock(p.poses[2].data()));
  EXPECT_FALSE(solver.hasBlock(p.poses[1].data()));
  EXPECT_THROW(solver.addParameterBlock(p.poses[0].data(), 7, &manifold, false), UsageError);  // twice
  EXPECT_THROW(solver.addParameterBlock(p.poses[1].data(), 6, &manifold, false), UsageError);  // size vs manifold
  // A residual over an unregistered block.
  EXPECT_THROW(solver.addResidual(p.res[0].cost, nullptr, blocksOf(p, p.res[0])), UsageError);
  // Wrong number of blocks.
  EXPECT_THROW(solver.addResidual(p.res[0].cost, nullptr, {p.poses[0].data()}), UsageError);
}

}  // namespace
}  // namespace linnet
