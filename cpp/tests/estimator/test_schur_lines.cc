// SchurLmSolver with mixed eliminated landmarks, inverse-depth points and Plücker lines (LineManifold), next to kept
// poses and kept 3-D anchors tied to lines, on a small stereo bundle: against Ceres at convergence, against the solver
// without elimination, and one step against the dense normal equations (with and without landmark_damping).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <ceres/normal_prior.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <Eigen/Dense>

#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/factors/point_factors.h"
#include "estimator/pose_prior_cost.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/schur_lm_solver.h"
#include "linnet/geometry/plucker.h"

namespace linnet {
namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

using testing::PosePrior;

// A kept 3-D "anchor" (Euclidean) pulled onto a line: r = w (p x v - n) / |v| (3 rows); with a prior on it, it gives
// the eliminated line a kept neighbour that is not a pose.
struct AnchorOnLine {
  explicit AnchorOnLine(double w) : w_(w) {}
  template <class T>
  bool operator()(const T* p, const T* L, T* r) const {
    const Eigen::Matrix<T, 3, 1> P(p[0], p[1], p[2]), n(L[0], L[1], L[2]), v(L[3], L[4], L[5]);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> res(r);
    res = (P.cross(v) - n) * (T(w_) / v.norm());
    return true;
  }
  double w_;
};

struct Manifolds {
  PoseManifold pose;
  LineManifold line;
  ceres::HuberLoss huber{1.0};
};

struct Bundle {
  std::vector<std::array<double, 7>> poses;
  std::vector<double> inv_depth;
  std::vector<std::array<double, 6>> lines;
  std::vector<std::array<double, 3>> anchors;
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  struct Res {
    ceres::CostFunction* cost;
    bool robust;
    std::vector<double*> blocks;
  };
  std::vector<Res> res;
  struct Block {
    double* data;
    int ambient;
    const ceres::Manifold* manifold;
    bool landmark;
  };
  /// Every block: poses, anchors (kept), inverse depths, lines (landmarks).
  std::vector<Block> blocks(const Manifolds& m) {
    std::vector<Block> out;
    for (auto& x : poses) out.push_back({x.data(), 7, &m.pose, false});
    for (auto& x : anchors) out.push_back({x.data(), 3, nullptr, false});
    for (double& d : inv_depth) out.push_back({&d, 1, nullptr, true});
    for (auto& x : lines) out.push_back({x.data(), kLineAmbientSize, &m.line, true});
    return out;
  }
};

// Four body poses moving right, 16 points (hosted in frame 0 or 1, seen in cam0 and cam1 of the others), 6 lines
// (seen in cam0 and cam1 of every frame; two of them hold an anchor), `noise_px` observation noise, starting values
// perturbed, a prior on the first pose.
Bundle makeBundle(unsigned seed, double noise_px, bool robust) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::normal_distribution<double> N(0.0, 1.0);
  const double f = 460.0, sqrt_info = f / 1.5, noise = noise_px / f;
  const Pose T_B_C0(expSO3(Vec3(0.01, -0.02, 0.015)), Vec3(-0.02, -0.06, 0.01));
  const Pose T_B_C1 = T_B_C0 * Pose(Quat::Identity(), Vec3(0.11, 0.0, 0.0));
  const Pose cams[2] = {T_B_C0, T_B_C1};
  std::vector<Pose> truth;
  for (int i = 0; i < 4; ++i)
    truth.emplace_back(expSO3(Vec3(0.01 * U(rng), 0.04 * i, 0.01 * U(rng))),
                       Vec3(0.25 * i, 0.05 * U(rng), 0.05 * i));
  const auto project = [&](const Pose& T_W_B, const Pose& T_B_C, const Vec3& p_W) {
    const Vec3 p = (T_W_B * T_B_C).inverse() * p_W;
    return Vec2(p.head<2>() / p.z() + noise * Vec2(N(rng), N(rng)));
  };
  Bundle b;  // all blocks first: the residuals keep pointers into the vectors
  b.poses.resize(4);
  b.inv_depth.resize(16);
  b.lines.resize(6);
  b.anchors.resize(2);
  for (std::size_t i = 0; i < 4; ++i)
    setPose(Pose(truth[i].q * expSO3(0.01 * Vec3(U(rng), U(rng), U(rng))),
                 truth[i].p + 0.03 * Vec3(U(rng), U(rng), U(rng))),
            b.poses[i].data());
  const auto add = [&](ceres::CostFunction* cost, bool rob, std::vector<double*> blocks) {
    b.costs.emplace_back(cost);
    b.res.push_back({cost, rob, std::move(blocks)});
  };
  for (std::size_t l = 0; l < 16; ++l) {
    const std::size_t host = l % 2;
    const Vec3 p_C(0.8 * U(rng), 0.6 * U(rng), 4.0 + 2.0 * U(rng));
    const Vec3 p_W = truth[host] * (T_B_C0 * p_C);
    b.inv_depth[l] = (1.0 / p_C.z()) * (1.0 + 0.05 * U(rng));
    const Vec2 uv_host = project(truth[host], T_B_C0, p_W);
    for (std::size_t j = 0; j < 4; ++j) {
      if (j == host) continue;
      for (const Pose& T_B_C : cams)
        add(new PointReprojectionFactor(uv_host, project(truth[j], T_B_C, p_W), T_B_C0, T_B_C, sqrt_info), robust,
            {b.poses[host].data(), b.poses[j].data(), &b.inv_depth[l]});
    }
  }
  const LineManifold line_manifold;
  for (std::size_t l = 0; l < 6; ++l) {
    const Vec3 mid(1.5 * U(rng), 0.8 * U(rng), 4.5 + 1.5 * U(rng));
    const Vec3 half(0.6 * U(rng), 0.8 + 0.3 * U(rng), 0.4 * U(rng));
    const Vec3 A = mid - half, B = mid + half;
    const Vec6 L = normalisePlucker(pluckerFromPoints(A, B));
    const double delta[4] = {0.01 * U(rng), 0.01 * U(rng), 0.01 * U(rng), 0.01 * U(rng)};
    line_manifold.Plus(L.data(), delta, b.lines[l].data());
    for (std::size_t j = 0; j < 4; ++j)
      for (const Pose& T_B_C : cams)
        add(new LineReprojectionFactor(project(truth[j], T_B_C, A), project(truth[j], T_B_C, B), T_B_C, sqrt_info),
            robust, {b.poses[j].data(), b.lines[l].data()});
    if (l < 2) {
      const Vec3 p0 = mid + 0.3 * half + 0.02 * Vec3(U(rng), U(rng), U(rng));
      b.anchors[l] = {p0.x() + 0.05, p0.y(), p0.z()};
      add(new ceres::AutoDiffCostFunction<AnchorOnLine, 3, 3, 6>(new AnchorOnLine(30.0)), false,
          {b.anchors[l].data(), b.lines[l].data()});
      add(new ceres::NormalPrior(Eigen::MatrixXd::Identity(3, 3), p0), false, {b.anchors[l].data()});
    }
  }
  add(new ceres::AutoDiffCostFunction<PosePrior, 6, 7>(new PosePrior(truth[0], 1e3)), false, {b.poses[0].data()});
  return b;
}

// Ceres to convergence; `lines_only`: every block but the lines held constant.
ceres::Solver::Summary solveCeres(Bundle& b, Manifolds& m, bool lines_only = false) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (const Bundle::Block& x : b.blocks(m)) {
    problem.AddParameterBlock(x.data, x.ambient, const_cast<ceres::Manifold*>(x.manifold));
    if (lines_only && x.manifold != &m.line) problem.SetParameterBlockConstant(x.data);
  }
  for (const auto& r : b.res) problem.AddResidualBlock(r.cost, r.robust ? &m.huber : nullptr, r.blocks);
  ceres::Solver::Options o;
  o.linear_solver_type = ceres::DENSE_QR;
  o.max_num_iterations = 100;
  o.function_tolerance = o.gradient_tolerance = o.parameter_tolerance = 1e-15;
  ceres::Solver::Summary s;
  ceres::Solve(o, &problem, &s);
  return s;
}

SchurLmSummary solveSchur(Bundle& b, const Manifolds& m, bool eliminate, const SchurLmOptions& o) {
  SchurLmSolver solver;
  for (const Bundle::Block& x : b.blocks(m))
    solver.addParameterBlock(x.data, x.ambient, x.manifold, eliminate && x.landmark);
  for (const auto& r : b.res) solver.addResidual(r.cost, r.robust ? &m.huber : nullptr, r.blocks);
  return solver.solve(o);
}

/// Largest difference of poses (position, rotation angle), anchors, inverse depths and unit lines (up to sign).
double maxDifference(const Bundle& a, const Bundle& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.poses.size(); ++i) {
    const Pose Ta = poseFromBlock(a.poses[i].data()), Tb = poseFromBlock(b.poses[i].data());
    d = std::max({d, (Ta.p - Tb.p).norm(), logSO3(Ta.q.conjugate() * Tb.q).norm()});
  }
  for (std::size_t i = 0; i < a.anchors.size(); ++i)
    d = std::max(d, (Vec3(a.anchors[i].data()) - Vec3(b.anchors[i].data())).norm());
  for (std::size_t l = 0; l < a.inv_depth.size(); ++l) d = std::max(d, std::abs(a.inv_depth[l] - b.inv_depth[l]));
  for (std::size_t l = 0; l < a.lines.size(); ++l) {
    const Vec6 La = normalisePlucker(Eigen::Map<const Vec6>(a.lines[l].data()));
    const Vec6 Lb = normalisePlucker(Eigen::Map<const Vec6>(b.lines[l].data()));
    d = std::max(d, std::min((La - Lb).norm(), (La + Lb).norm()));
  }
  return d;
}

TEST(SchurLmLines, ReachesTheCeresMinimumWithPointsAndLines) {
  Manifolds m;
  Bundle a = makeBundle(3, 0.7, true), b = makeBundle(3, 0.7, true);
  const ceres::Solver::Summary cs = solveCeres(a, m);
  ASSERT_TRUE(cs.IsSolutionUsable()) << cs.BriefReport();
  // Default options, landmark_damping included: it slows the lines down (here ~350 iterations instead of ~20 with
  // landmark_damping = 0) but must not move the minimum.
  SchurLmOptions o;
  o.max_iterations = 1000;
  // Converged: a step that lowers the cost by less than 1e-13 of it (tighter stops hang on the rounding of the cost,
  // where no step is accepted any more; the minimum itself is checked below).
  o.function_tolerance = 1e-13;
  const SchurLmSummary s = solveSchur(b, m, true, o);
  EXPECT_TRUE(s.converged);
  EXPECT_NEAR(s.initial_cost, cs.initial_cost, 1e-9 * cs.initial_cost);
  EXPECT_LT(s.final_cost, 0.1 * s.initial_cost);  // down to the noise floor
  EXPECT_NEAR(s.final_cost, cs.final_cost, 1e-6 * cs.final_cost);
  EXPECT_LT(maxDifference(a, b), 1e-6);
}

TEST(SchurLmLines, LineIterationsReachTheMinimumSooner) {
  // The per-frame use: few joint steps. Under landmark_damping the lines move only part of the way per step; with
  // their own iterations between the steps, 15 steps reach the minimum that the plain solver is still far from.
  Manifolds m;
  Bundle a = makeBundle(3, 0.7, true), b = makeBundle(3, 0.7, true), c = makeBundle(3, 0.7, true);
  ASSERT_TRUE(solveCeres(a, m).IsSolutionUsable());
  SchurLmOptions o;
  o.max_iterations = 15;
  o.function_tolerance = 0.0;
  const SchurLmSummary plain = solveSchur(b, m, true, o);
  o.landmark_iterations = 5;
  const SchurLmSummary embedded = solveSchur(c, m, true, o);
  EXPECT_LT(embedded.final_cost, plain.final_cost);
  EXPECT_GT(maxDifference(a, b), 1e-4);
  EXPECT_LT(maxDifference(a, c), 1e-6);
}

TEST(SchurLmLines, LineIterationsMoveOnlyTheLinesToTheirOptimumGivenTheRest) {
  // With no joint step (max_iterations = 0) only the iterations before the first one run: every line alone, the
  // poses, anchors and points held. The lines must reach what Ceres finds with everything else held constant (no
  // robust loss: with the poses held off their optimum many residuals would sit in the Huber loss' linear part,
  // where the reweighted steps converge only linearly).
  Manifolds m;
  Bundle a = makeBundle(7, 0.7, false), b = makeBundle(7, 0.7, false);
  const Bundle start = makeBundle(7, 0.7, false);
  SchurLmOptions o;
  o.max_iterations = 0;
  o.landmark_iterations = 10;
  const SchurLmSummary s = solveSchur(b, m, true, o);
  EXPECT_EQ(s.iterations, 0);
  const ceres::Solver::Summary cs = solveCeres(a, m, true);
  ASSERT_TRUE(cs.IsSolutionUsable());
  for (std::size_t i = 0; i < b.poses.size(); ++i) EXPECT_EQ(b.poses[i], start.poses[i]);
  for (std::size_t i = 0; i < b.anchors.size(); ++i) EXPECT_EQ(b.anchors[i], start.anchors[i]);
  EXPECT_EQ(b.inv_depth, start.inv_depth);
  EXPECT_LT(maxDifference(a, b), 1e-4);  // a line's iterations stop once a step gains < 0.1 % of its cost
  EXPECT_GT(maxDifference(start, b), 1e-3);  // the perturbed lines really moved
}

TEST(SchurLmLines, EliminatingLinesAndPointsGivesTheSameSteps) {
  Manifolds m;
  Bundle a = makeBundle(5, 1.0, true), b = makeBundle(5, 1.0, true);
  SchurLmOptions o;
  o.max_iterations = 3;
  o.landmark_damping = 0.0;  // only eliminated blocks get it: the systems differ otherwise
  const SchurLmSummary sa = solveSchur(a, m, true, o);
  const SchurLmSummary sb = solveSchur(b, m, false, o);
  EXPECT_EQ(sa.successful_steps, sb.successful_steps);
  EXPECT_NEAR(sa.final_cost, sb.final_cost, 1e-9 * sa.initial_cost);
  EXPECT_LT(maxDifference(a, b), 1e-9);
}

TEST(SchurLmLines, GaussNewtonStepMatchesTheDenseNormalEquations) {
  Manifolds m;
  Bundle b = makeBundle(9, 0.5, false);
  // Tangent layout: the blocks in order, each at its offset.
  const std::vector<Bundle::Block> blocks = b.blocks(m);
  std::map<const double*, int> offset;
  int n = 0, rows = 0;
  for (const Bundle::Block& x : blocks) {
    offset[x.data] = n;
    n += x.manifold != nullptr ? x.manifold->TangentSize() : x.ambient;
  }
  for (const auto& r : b.res) rows += r.cost->num_residuals();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows, n);
  Eigen::VectorXd res(rows);
  int row = 0;
  for (const auto& r : b.res) {
    const int nr = r.cost->num_residuals();
    std::vector<RowMajor> jac;
    std::vector<double*> jac_ptr;
    for (std::size_t k = 0; k < r.blocks.size(); ++k) jac.emplace_back(nr, r.cost->parameter_block_sizes()[k]);
    for (auto& j : jac) jac_ptr.push_back(j.data());
    ASSERT_TRUE(r.cost->Evaluate(r.blocks.data(), res.data() + row, jac_ptr.data()));
    for (std::size_t k = 0; k < r.blocks.size(); ++k) {
      const auto it = std::find_if(blocks.begin(), blocks.end(),
                                   [&](const Bundle::Block& x) { return x.data == r.blocks[k]; });
      const int tangent = it->manifold != nullptr ? it->manifold->TangentSize() : it->ambient;
      RowMajor plus = RowMajor::Identity(it->ambient, tangent);
      if (it->manifold != nullptr) it->manifold->PlusJacobian(it->data, plus.data());
      J.block(row, offset.at(it->data), nr, plus.cols()) = jac[k] * plus;
    }
    row += nr;
  }
  // One nearly undamped step of the solver (lines and points eliminated) solves (H + lambda I_lines) dx = -g, with
  // lambda = landmark_damping on the lines' tangent entries only: 0 (Gauss-Newton), then the default.
  for (const double lambda : {0.0, SchurLmOptions().landmark_damping}) {
    Eigen::MatrixXd H = J.transpose() * J;
    for (const Bundle::Block& x : blocks)
      if (x.landmark && x.manifold != nullptr) H.diagonal().segment(offset.at(x.data), 4).array() += lambda;
    const Eigen::VectorXd dx = H.ldlt().solve(-J.transpose() * res);
    ASSERT_TRUE(dx.allFinite());
    EXPECT_GT(dx.norm(), 1e-3);  // a real step
    Bundle expected = makeBundle(9, 0.5, false), solved = makeBundle(9, 0.5, false);
    const std::vector<Bundle::Block> eb = expected.blocks(m);
    for (std::size_t i = 0; i < eb.size(); ++i) {
      const double* d = dx.data() + offset.at(blocks[i].data);
      std::vector<double> out(eb[i].data, eb[i].data + eb[i].ambient);
      if (eb[i].manifold != nullptr) eb[i].manifold->Plus(eb[i].data, d, out.data());
      for (int k = 0; k < eb[i].ambient; ++k) eb[i].data[k] = eb[i].manifold != nullptr ? out[k] : out[k] + d[k];
    }
    SchurLmOptions o;
    o.max_iterations = 1;
    o.initial_radius = 1e20;
    o.landmark_damping = lambda;
    const SchurLmSummary s = solveSchur(solved, m, true, o);
    EXPECT_NEAR(s.initial_cost, 0.5 * res.squaredNorm(), 1e-12 * s.initial_cost);
    ASSERT_EQ(s.successful_steps, 1);
    EXPECT_LT(maxDifference(solved, expected), 1e-8) << "landmark_damping " << lambda;
  }
}

}  // namespace
}  // namespace linnet
