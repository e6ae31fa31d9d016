// SchurLmSolver with mixed landmarks: inverse-depth points (1-D) and Plücker lines (6-D ambient, 4-D LineManifold
// tangent), both eliminated, on a small stereo bundle with a prior on the first pose. Checked against Ceres at
// convergence, against the same solver without elimination, and one Gauss-Newton step against the dense normal
// equations assembled here from the factors' tangent Jacobians.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <memory>
#include <random>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>
#include <ceres/solver.h>
#include <Eigen/Dense>

#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/factors/point_factors.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/schur_lm_solver.h"
#include "linnet/geometry/plucker.h"

namespace linnet {
namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Pose prior [p - p0, 2 vec(q0^-1 q)] * weight on a [p, q xyzw] block.
struct PosePrior {
  PosePrior(const Pose& T0, double w) : T0_(T0), w_(w) {}
  template <class T>
  bool operator()(const T* x, T* r) const {
    const Eigen::Quaternion<T> q(x[6], x[3], x[4], x[5]);
    const Eigen::Quaternion<T> dq = T0_.q.conjugate().cast<T>() * q;
    for (int k = 0; k < 3; ++k) r[k] = T(w_) * (x[k] - T(T0_.p[k]));
    r[3] = T(2.0 * w_) * dq.x();
    r[4] = T(2.0 * w_) * dq.y();
    r[5] = T(2.0 * w_) * dq.z();
    return true;
  }
  Pose T0_;
  double w_;
};

struct Bundle {
  std::vector<std::array<double, 7>> poses;
  std::vector<double> inv_depth;
  std::vector<std::array<double, 6>> lines;
  std::vector<std::unique_ptr<ceres::CostFunction>> costs;
  struct Res {
    ceres::CostFunction* cost;
    bool robust;
    std::vector<int> poses;
    int point = -1, line = -1;  // the landmark block (last), if any
  };
  std::vector<Res> res;
};

// Four body poses moving right, 16 points (hosted in frame 0 or 1, seen in cam0 and cam1 of the others) and 6 lines
// (seen in cam0 and cam1 of every frame), `noise_px` observation noise, starting values perturbed.
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
    truth.emplace_back(expSO3(Vec3(0.01 * U(rng), 0.04 * i, 0.01 * U(rng))), Vec3(0.25 * i, 0.05 * U(rng), 0.05 * i));
  const auto project = [&](const Pose& T_W_B, const Pose& T_B_C, const Vec3& p_W) {
    const Vec3 p = (T_W_B * T_B_C).inverse() * p_W;
    return Vec2(p.head<2>() / p.z() + noise * Vec2(N(rng), N(rng)));
  };
  Bundle b;
  for (const Pose& T : truth) {
    std::array<double, 7> x{};
    setPose(Pose(T.q * expSO3(0.01 * Vec3(U(rng), U(rng), U(rng))), T.p + 0.03 * Vec3(U(rng), U(rng), U(rng))),
            x.data());
    b.poses.push_back(x);
  }
  b.res.reserve(200);
  for (int l = 0; l < 16; ++l) {
    const int host = l % 2;
    const Vec3 p_C(0.8 * U(rng), 0.6 * U(rng), 4.0 + 2.0 * U(rng));
    const Vec3 p_W = truth[static_cast<std::size_t>(host)] * (T_B_C0 * p_C);
    b.inv_depth.push_back((1.0 / p_C.z()) * (1.0 + 0.05 * U(rng)));
    const Vec2 uv_host = project(truth[static_cast<std::size_t>(host)], T_B_C0, p_W);
    for (int j = 0; j < 4; ++j) {
      if (j == host) continue;
      for (const Pose& T_B_C : cams) {
        b.costs.push_back(std::make_unique<PointReprojectionFactor>(
            uv_host, project(truth[static_cast<std::size_t>(j)], T_B_C, p_W), T_B_C0, T_B_C, sqrt_info));
        b.res.push_back({b.costs.back().get(), robust, {host, j}, l, -1});
      }
    }
  }
  const LineManifold line_manifold;
  for (int l = 0; l < 6; ++l) {
    const Vec3 mid(1.5 * U(rng), 0.8 * U(rng), 4.5 + 1.5 * U(rng));
    const Vec3 half(0.6 * U(rng), 0.8 + 0.3 * U(rng), 0.4 * U(rng));
    const Vec3 A = mid - half, B = mid + half;
    const Vec6 L = normalisePlucker(pluckerFromPoints(A, B));
    std::array<double, 6> x{};
    const double delta[4] = {0.01 * U(rng), 0.01 * U(rng), 0.01 * U(rng), 0.01 * U(rng)};
    line_manifold.Plus(L.data(), delta, x.data());
    b.lines.push_back(x);
    for (int j = 0; j < 4; ++j)
      for (const Pose& T_B_C : cams) {
        const Pose& T = truth[static_cast<std::size_t>(j)];
        b.costs.push_back(std::make_unique<LineReprojectionFactor>(project(T, T_B_C, A), project(T, T_B_C, B),
                                                                   T_B_C, sqrt_info));
        b.res.push_back({b.costs.back().get(), robust, {j}, -1, l});
      }
  }
  b.costs.push_back(std::make_unique<ceres::AutoDiffCostFunction<PosePrior, 6, 7>>(new PosePrior(truth[0], 1e3)));
  b.res.push_back({b.costs.back().get(), false, {0}, -1, -1});
  return b;
}

std::vector<double*> blocksOf(Bundle& b, const Bundle::Res& r) {
  std::vector<double*> out;
  for (int i : r.poses) out.push_back(b.poses[static_cast<std::size_t>(i)].data());
  if (r.point >= 0) out.push_back(&b.inv_depth[static_cast<std::size_t>(r.point)]);
  if (r.line >= 0) out.push_back(b.lines[static_cast<std::size_t>(r.line)].data());
  return out;
}

struct Manifolds {
  PoseManifold pose;
  LineManifold line;
  ceres::HuberLoss huber{1.0};
};

ceres::Solver::Summary solveCeres(Bundle& b, Manifolds& m) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (auto& x : b.poses) problem.AddParameterBlock(x.data(), 7, &m.pose);
  for (auto& x : b.lines) problem.AddParameterBlock(x.data(), 6, &m.line);
  for (const auto& r : b.res) problem.AddResidualBlock(r.cost, r.robust ? &m.huber : nullptr, blocksOf(b, r));
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
  for (auto& x : b.poses) solver.addParameterBlock(x.data(), 7, &m.pose, false);
  for (double& d : b.inv_depth) solver.addParameterBlock(&d, 1, nullptr, eliminate);
  for (auto& x : b.lines) solver.addParameterBlock(x.data(), kLineAmbientSize, &m.line, eliminate);
  for (const auto& r : b.res) solver.addResidual(r.cost, r.robust ? &m.huber : nullptr, blocksOf(b, r));
  return solver.solve(o);
}

/// Largest difference of poses (position, rotation angle), inverse depths and unit lines (up to sign).
double maxDifference(const Bundle& a, const Bundle& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.poses.size(); ++i) {
    const Pose Ta = poseFromBlock(a.poses[i].data()), Tb = poseFromBlock(b.poses[i].data());
    d = std::max({d, (Ta.p - Tb.p).norm(), logSO3(Ta.q.conjugate() * Tb.q).norm()});
  }
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
  SchurLmOptions o;
  o.max_iterations = 100;
  o.function_tolerance = 1e-15;
  const SchurLmSummary s = solveSchur(b, m, true, o);
  EXPECT_NEAR(s.initial_cost, cs.initial_cost, 1e-9 * cs.initial_cost);
  EXPECT_LT(s.final_cost, 0.01 * s.initial_cost);
  EXPECT_NEAR(s.final_cost, cs.final_cost, 1e-6 * cs.final_cost);
  EXPECT_LT(maxDifference(a, b), 1e-6);
}

TEST(SchurLmLines, EliminatingLinesAndPointsGivesTheSameSteps) {
  Manifolds m;
  Bundle a = makeBundle(5, 1.0, true), b = makeBundle(5, 1.0, true);
  SchurLmOptions o;
  o.max_iterations = 3;
  const SchurLmSummary sa = solveSchur(a, m, true, o);
  const SchurLmSummary sb = solveSchur(b, m, false, o);
  EXPECT_EQ(sa.successful_steps, sb.successful_steps);
  EXPECT_NEAR(sa.final_cost, sb.final_cost, 1e-9 * sa.initial_cost);
  EXPECT_LT(maxDifference(a, b), 1e-9);
}

TEST(SchurLmLines, GaussNewtonStepMatchesTheDenseNormalEquations) {
  Manifolds m;
  Bundle b = makeBundle(9, 0.5, false);
  // Tangent layout: poses (6 each), inverse depths (1 each), lines (4 each).
  const int np = static_cast<int>(b.poses.size()), nd = static_cast<int>(b.inv_depth.size());
  const int n = 6 * np + nd + 4 * static_cast<int>(b.lines.size());
  int rows = 0;
  for (const auto& r : b.res) rows += r.cost->num_residuals();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(rows, n);
  Eigen::VectorXd res(rows);
  int row = 0;
  for (const auto& r : b.res) {
    const std::vector<double*> blocks = blocksOf(b, r);
    const int nr = r.cost->num_residuals();
    std::vector<RowMajor> jac;
    std::vector<double*> jac_ptr;
    for (std::size_t k = 0; k < blocks.size(); ++k) jac.emplace_back(nr, r.cost->parameter_block_sizes()[k]);
    for (auto& j : jac) jac_ptr.push_back(j.data());
    ASSERT_TRUE(r.cost->Evaluate(blocks.data(), res.data() + row, jac_ptr.data()));
    std::size_t k = 0;
    for (int i : r.poses) {
      RowMajor plus(7, 6);
      m.pose.PlusJacobian(blocks[k], plus.data());
      J.block(row, 6 * i, nr, 6) = jac[k++] * plus;
    }
    if (r.point >= 0) J.block(row, 6 * np + r.point, nr, 1) = jac[k];
    if (r.line >= 0) {
      RowMajor plus(6, 4);
      m.line.PlusJacobian(blocks[k], plus.data());
      J.block(row, 6 * np + nd + 4 * r.line, nr, 4) = jac[k] * plus;
    }
    row += nr;
  }
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd dx = H.ldlt().solve(-J.transpose() * res);
  ASSERT_TRUE(dx.allFinite());
  // Expected values after the step.
  Bundle expected = makeBundle(9, 0.5, false);
  for (int i = 0; i < np; ++i) {
    std::array<double, 7> out{};
    m.pose.Plus(expected.poses[static_cast<std::size_t>(i)].data(), dx.data() + 6 * i, out.data());
    expected.poses[static_cast<std::size_t>(i)] = out;
  }
  for (int l = 0; l < nd; ++l) expected.inv_depth[static_cast<std::size_t>(l)] += dx(6 * np + l);
  for (std::size_t l = 0; l < expected.lines.size(); ++l) {
    std::array<double, 6> out{};
    m.line.Plus(expected.lines[l].data(), dx.data() + 6 * np + nd + 4 * static_cast<int>(l), out.data());
    expected.lines[l] = out;
  }
  // One nearly undamped step of the solver, lines and points eliminated.
  SchurLmOptions o;
  o.max_iterations = 1;
  o.initial_radius = 1e20;
  const SchurLmSummary s = solveSchur(b, m, true, o);
  EXPECT_NEAR(s.initial_cost, 0.5 * res.squaredNorm(), 1e-12 * s.initial_cost);
  ASSERT_EQ(s.successful_steps, 1);
  EXPECT_GT(dx.norm(), 1e-3);  // a real step
  EXPECT_LT(maxDifference(b, expected), 1e-8);
}

}  // namespace
}  // namespace linnet
