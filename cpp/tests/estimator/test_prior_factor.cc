// PriorFactor through the shared Jacobian checker (pose, Euclidean and a generic manifold block, away from
// x0), and marginalisation of a nonlinear problem with PoseManifold blocks: minimum at x0 for consistent
// data, gradient and curvature of the prior against the exact marginal cost min_A F, and re-marginalisation
// equal to one-shot elimination.
#include "linnet/estimator/factors/prior_factor.h"

#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "linnet/core/error.h"
#include "linnet/core/pose.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/marginaliser.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

using Block7 = std::array<double, 7>;

// ---- nonlinear test residuals (autodiff; their Jacobians are exact) ----

/// Absolute pose measurement: [p - p_m; 2 vec(q_m^-1 q)] * w.
struct PosePriorFunctor {
  Pose meas;
  double w;
  template <class T>
  bool operator()(const T* x, T* r) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> p(x);
    Eigen::Map<const Eigen::Quaternion<T>> q(x + 3);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> res(r);
    res.template head<3>() = T(w) * (p - meas.p.cast<T>());
    res.template tail<3>() = T(2.0 * w) * (meas.q.conjugate().cast<T>() * q).vec();
    return true;
  }
};

/// Relative pose measurement between a and b: [R_a^T (p_b - p_a) - t_m; 2 vec(q_m^-1 q_a^-1 q_b)] * w.
struct RelativePoseFunctor {
  Pose meas;
  double w;
  template <class T>
  bool operator()(const T* a, const T* b, T* r) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> pa(a), pb(b);
    Eigen::Map<const Eigen::Quaternion<T>> qa(a + 3), qb(b + 3);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> res(r);
    res.template head<3>() = T(w) * (qa.conjugate() * (pb - pa) - meas.p.cast<T>());
    res.template tail<3>() = T(2.0 * w) * (meas.q.conjugate().cast<T>() * qa.conjugate() * qb).vec();
    return true;
  }
};

/// A landmark c (Euclidean, 3) seen from pose a: R_a^T (c - p_a) - m.
struct LandmarkFunctor {
  Vec3 meas;
  double w;
  template <class T>
  bool operator()(const T* a, const T* c, T* r) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> pa(a), pc(c);
    Eigen::Map<const Eigen::Quaternion<T>> qa(a + 3);
    Eigen::Map<Eigen::Matrix<T, 3, 1>> res(r);
    res = T(w) * (qa.conjugate() * (pc - pa) - meas.cast<T>());
    return true;
  }
};

std::shared_ptr<ceres::CostFunction> posePrior(const Pose& m, double w) {
  return std::make_shared<ceres::AutoDiffCostFunction<PosePriorFunctor, 6, 7>>(new PosePriorFunctor{m, w});
}
std::shared_ptr<ceres::CostFunction> relative(const Pose& m, double w) {
  return std::make_shared<ceres::AutoDiffCostFunction<RelativePoseFunctor, 6, 7, 7>>(
      new RelativePoseFunctor{m, w});
}
std::shared_ptr<ceres::CostFunction> landmark(const Vec3& m, double w) {
  return std::make_shared<ceres::AutoDiffCostFunction<LandmarkFunctor, 3, 7, 3>>(new LandmarkFunctor{m, w});
}

Block7 block(const Pose& T) {
  Block7 b;
  setPose(T, b.data());
  return b;
}

Pose randomPose(std::mt19937& rng, double rot, double trans) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  return Pose(expSO3(rot * Vec3(u(rng), u(rng), u(rng))), trans * Vec3(u(rng), u(rng), u(rng)));
}

// ---- (b) Jacobians through the checker ----

TEST(PriorFactor, JacobiansMatchThroughManifoldsAwayFromX0) {
  std::mt19937 rng(31);
  std::normal_distribution<double> n(0.0, 1.0);
  const PoseManifold pose_manifold;
  const ceres::EigenQuaternionManifold quat_manifold;  // exercises the generic (central-difference) path
  for (int trial = 0; trial < 20; ++trial) {
    auto prior = std::make_shared<MarginalizationPrior>();
    const Block7 x0_pose = block(randomPose(rng, 2.0, 3.0));
    const Eigen::Quaterniond q0 = randomPose(rng, 2.0, 0.0).q;
    prior->keys = {5, 6, 7};
    prior->ambient_sizes = {7, 3, 4};
    prior->tangent_sizes = {6, 3, 3};
    prior->tangent_offsets = {0, 6, 9};
    prior->x0 = {std::vector<double>(x0_pose.begin(), x0_pose.end()),
                 {0.1, -0.2, 0.3},
                 {q0.x(), q0.y(), q0.z(), q0.w()}};
    prior->manifolds = {&pose_manifold, nullptr, &quat_manifold};
    prior->J = Eigen::MatrixXd::NullaryExpr(10, 12, [&] { return n(rng); });
    prior->r = Eigen::VectorXd::NullaryExpr(10, [&] { return n(rng); });
    const PriorFactor f(prior);
    ASSERT_EQ(f.num_residuals(), 10);
    ASSERT_EQ(f.parameter_block_sizes(), (std::vector<int32_t>{7, 3, 4}));

    // Evaluate well away from x0: up to ~0.9 rad and 1 m.
    Block7 x_pose = block(poseFromBlock(x0_pose.data()) * randomPose(rng, 0.5, 0.6));
    double x_e[3] = {0.5, 0.4, -0.7};
    const Eigen::Quaterniond q = q0 * expSO3(Vec3(0.4, -0.3, 0.2));
    double x_q[4] = {q.x(), q.y(), q.z(), q.w()};
    ASSERT_TRUE(testing::jacobiansMatch(f, {x_pose.data(), x_e, x_q},
                                        {&pose_manifold, nullptr, &quat_manifold}, 1e-6))
        << "trial " << trial;

    // At x0 the residual is r.
    Eigen::VectorXd res(10);
    const double* at_x0[3] = {prior->x0[0].data(), prior->x0[1].data(), prior->x0[2].data()};
    ASSERT_TRUE(f.Evaluate(at_x0, res.data(), nullptr));
    EXPECT_LT((res - prior->r).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(PriorFactor, RejectsInconsistentPriors) {
  auto prior = std::make_shared<MarginalizationPrior>();
  prior->keys = {1};
  prior->ambient_sizes = {3};
  prior->tangent_sizes = {3};
  prior->tangent_offsets = {0};
  prior->x0 = {{0.0, 0.0, 0.0}};
  prior->manifolds = {nullptr};
  prior->J = Eigen::MatrixXd::Identity(3, 4);  // one column too many
  prior->r = Eigen::VectorXd::Zero(3);
  EXPECT_THROW(PriorFactor{prior}, UsageError);
  EXPECT_THROW(PriorFactor{nullptr}, UsageError);
}

// ---- (c) a nonlinear problem with PoseManifold blocks ----

/// Pose A (dropped), pose B and landmark c (kept). The residuals that touch A.
struct NonlinearScene {
  Pose A, B;
  Vec3 c;
  std::vector<std::shared_ptr<ceres::CostFunction>> costs;  // prior(A), rel(A,B), lm(A,c)
  void build(const Pose& meas_A, const Pose& meas_AB, const Vec3& meas_Ac) {
    costs = {posePrior(meas_A, 10.0), relative(meas_AB, 20.0), landmark(meas_Ac, 5.0)};
  }
};

std::shared_ptr<const MarginalizationPrior> marginaliseA(const NonlinearScene& s, const PoseManifold* pm) {
  Marginaliser m;
  const Block7 a = block(s.A), b = block(s.B);
  m.addParameterBlock(0, a.data(), 7, pm);
  m.addParameterBlock(1, b.data(), 7, pm);
  m.addParameterBlock(2, s.c.data(), 3, nullptr);
  m.addResidual(s.costs[0], nullptr, {0});
  m.addResidual(s.costs[1], nullptr, {0, 1});
  m.addResidual(s.costs[2], nullptr, {0, 2});
  return m.marginalise({0});
}

/// Full cost of the residuals touching A, at A (pose block), B, c. Ceres convention: 1/2 sum r^2.
double costF(const NonlinearScene& s, const double* a, const double* b, const double* c) {
  double total = 0.0, r[6];
  const double* p0[1] = {a};
  s.costs[0]->Evaluate(p0, r, nullptr);
  for (int i = 0; i < 6; ++i) total += 0.5 * r[i] * r[i];
  const double* p1[2] = {a, b};
  s.costs[1]->Evaluate(p1, r, nullptr);
  for (int i = 0; i < 6; ++i) total += 0.5 * r[i] * r[i];
  const double* p2[2] = {a, c};
  s.costs[2]->Evaluate(p2, r, nullptr);
  for (int i = 0; i < 3; ++i) total += 0.5 * r[i] * r[i];
  return total;
}

/// min over A of F(A, B, c), A started at `a` and written back. The exact marginal cost.
double marginalCost(const NonlinearScene& s, Block7* a, const double* b, const double* c, PoseManifold* pm) {
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  Block7 bb;
  std::copy(b, b + 7, bb.begin());
  Vec3 cc(c[0], c[1], c[2]);
  problem.AddParameterBlock(a->data(), 7, pm);
  problem.AddParameterBlock(bb.data(), 7, pm);
  problem.AddParameterBlock(cc.data(), 3);
  problem.AddResidualBlock(s.costs[0].get(), nullptr, a->data());
  problem.AddResidualBlock(s.costs[1].get(), nullptr, a->data(), bb.data());
  problem.AddResidualBlock(s.costs[2].get(), nullptr, a->data(), cc.data());
  problem.SetParameterBlockConstant(bb.data());
  problem.SetParameterBlockConstant(cc.data());
  ceres::Solver::Options o;
  o.max_num_iterations = 100;
  o.function_tolerance = o.gradient_tolerance = o.parameter_tolerance = 1e-16;
  o.linear_solver_type = ceres::DENSE_QR;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  return costF(s, a->data(), bb.data(), cc.data());
}

double priorCost(const PriorFactor& f, const double* b, const double* c) {
  Eigen::VectorXd r(f.num_residuals());
  const double* p[2] = {b, c};
  f.Evaluate(p, r.data(), nullptr);
  return 0.5 * r.squaredNorm();
}

TEST(PriorFactor, NonlinearConsistentDataHasItsMinimumAtX0) {
  std::mt19937 rng(32);
  PoseManifold pm;
  NonlinearScene s;
  s.A = randomPose(rng, 1.0, 2.0);
  s.B = s.A * randomPose(rng, 0.5, 1.0);
  s.c = Vec3(1.0, -2.0, 4.0);
  s.build(s.A, s.A.inverse() * s.B, s.A.inverse() * s.c);  // exact measurements
  auto prior = marginaliseA(s, &pm);
  ASSERT_TRUE(prior);
  ASSERT_EQ(prior->keys, (std::vector<BlockKey>{1, 2}));
  EXPECT_EQ(prior->J.rows(), 9);  // B (6) and c (3), fully observed
  EXPECT_LT(prior->r.norm(), 1e-10);
  EXPECT_LT((prior->J.transpose() * prior->r).norm(), 1e-10);

  // Second-order agreement with the exact marginal cost m(x) = min_A F(A, x) around x0 (m(x0) = 0 here).
  const PriorFactor f(prior);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::Matrix<double, 9, 1> d;
    for (int i = 0; i < 9; ++i) d(i) = n(rng);
    d *= 1e-3 / d.norm();
    Block7 b;
    const Block7 b0 = block(s.B);
    pm.Plus(b0.data(), d.data(), b.data());
    const Vec3 c = s.c + d.tail<3>();
    Block7 a = block(s.A);
    const double exact = marginalCost(s, &a, b.data(), c.data(), &pm);
    const double approx = priorCost(f, b.data(), c.data());
    EXPECT_GT(approx, 0.0);
    EXPECT_NEAR(approx, exact, 2e-3 * exact) << "trial " << trial;
  }
}

TEST(PriorFactor, NonlinearGradientMatchesTheMarginalCost) {
  std::mt19937 rng(33);
  PoseManifold pm;
  NonlinearScene s;
  s.A = randomPose(rng, 1.0, 2.0);
  s.B = s.A * randomPose(rng, 0.5, 1.0);
  s.c = Vec3(-1.0, 0.5, 3.0);
  // Inconsistent measurements: x0 is not a minimum, the prior carries a gradient.
  s.build(s.A * randomPose(rng, 0.05, 0.1), randomPose(rng, 0.05, 0.1) * (s.A.inverse() * s.B),
          s.A.inverse() * s.c + Vec3(0.05, -0.03, 0.02));
  // Put A at its conditional optimum given B and c, as after a solve: then d m / d x = dF / dx (envelope
  // theorem).
  Block7 a = block(s.A);
  const Block7 b0 = block(s.B);
  const double m0 = marginalCost(s, &a, b0.data(), s.c.data(), &pm);
  s.A = poseFromBlock(a.data());
  auto prior = marginaliseA(s, &pm);
  ASSERT_TRUE(prior);
  const PriorFactor f(prior);
  const Eigen::VectorXd g_prior = prior->J.transpose() * prior->r;

  // Numeric gradient of F w.r.t. the kept tangent [dB (6), dc (3)] with A fixed at its optimum.
  Eigen::VectorXd g_num(9);
  const double h = 1e-6;
  for (int i = 0; i < 9; ++i) {
    Eigen::Matrix<double, 9, 1> d = Eigen::Matrix<double, 9, 1>::Zero();
    double fp = 0.0, fm = 0.0;
    for (double sign : {1.0, -1.0}) {
      d(i) = sign * h;
      Block7 b;
      pm.Plus(b0.data(), d.data(), b.data());
      const Vec3 c = s.c + d.tail<3>();
      (sign > 0 ? fp : fm) = costF(s, a.data(), b.data(), c.data());
    }
    g_num(i) = (fp - fm) / (2.0 * h);
  }
  EXPECT_LT((g_prior - g_num).cwiseAbs().maxCoeff(), 1e-5 * (1.0 + g_num.cwiseAbs().maxCoeff()))
      << g_prior.transpose() << "\n"
      << g_num.transpose();
  EXPECT_GT(g_num.norm(), 1e-2);  // the test is not vacuous

  // Cost differences agree to second order (Gauss-Newton curvature; the residuals here are small).
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::Matrix<double, 9, 1> d;
    for (int i = 0; i < 9; ++i) d(i) = n(rng);
    d *= 1e-3 / d.norm();
    Block7 b, a_t = a;
    pm.Plus(b0.data(), d.data(), b.data());
    const Vec3 c = s.c + d.tail<3>();
    const double dm = marginalCost(s, &a_t, b.data(), c.data(), &pm) - m0;
    const double dp = priorCost(f, b.data(), c.data()) - prior->costAtX0();
    EXPECT_NEAR(dp, dm, 0.02 * std::abs(dm) + 1e-9) << "trial " << trial;
  }
}

// ---- (d) re-marginalising a prior with pose blocks ----

TEST(PriorFactor, RemarginalisationEqualsOneShotEliminationOnPoses) {
  std::mt19937 rng(34);
  PoseManifold pm;
  const Pose A = randomPose(rng, 1.0, 2.0), B = A * randomPose(rng, 0.3, 1.0),
             C = B * randomPose(rng, 0.3, 1.0);
  const Vec3 c(0.5, 1.0, 5.0);
  auto noisy = [&](const Pose& T) { return T * randomPose(rng, 0.02, 0.05); };
  auto pA = posePrior(noisy(A), 10.0);
  auto rAB = relative(noisy(A.inverse() * B), 20.0), rBC = relative(noisy(B.inverse() * C), 20.0);
  auto lA = landmark(A.inverse() * c + Vec3(0.01, 0.0, -0.02), 5.0);
  auto lB = landmark(B.inverse() * c + Vec3(-0.02, 0.01, 0.0), 5.0);
  const Block7 a = block(A), b = block(B), cc = block(C);
  // Keys: 0 A, 1 B, 2 C, 3 landmark.
  auto registerAll = [&](Marginaliser& m) {
    m.addParameterBlock(0, a.data(), 7, &pm);
    m.addParameterBlock(1, b.data(), 7, &pm);
    m.addParameterBlock(2, cc.data(), 7, &pm);
    m.addParameterBlock(3, c.data(), 3, nullptr);
  };

  Marginaliser first;
  registerAll(first);
  first.addResidual(pA, nullptr, {0});
  first.addResidual(rAB, nullptr, {0, 1});
  first.addResidual(lA, nullptr, {0, 3});
  auto p1 = first.marginalise({0});
  ASSERT_TRUE(p1);
  ASSERT_EQ(p1->keys, (std::vector<BlockKey>{1, 3}));

  Marginaliser second;
  registerAll(second);
  second.addResidual(std::make_shared<PriorFactor>(p1), nullptr, p1->keys);
  second.addResidual(rBC, nullptr, {1, 2});
  second.addResidual(lB, nullptr, {1, 3});
  auto p2 = second.marginalise({1});
  ASSERT_TRUE(p2);

  Marginaliser once;
  registerAll(once);
  once.addResidual(pA, nullptr, {0});
  once.addResidual(rAB, nullptr, {0, 1});
  once.addResidual(lA, nullptr, {0, 3});
  once.addResidual(rBC, nullptr, {1, 2});
  once.addResidual(lB, nullptr, {1, 3});
  auto p12 = once.marginalise({0, 1});
  ASSERT_TRUE(p12);
  ASSERT_EQ(p2->keys, p12->keys);
  EXPECT_EQ(p2->keys, (std::vector<BlockKey>{2, 3}));
  const Eigen::MatrixXd H2 = p2->J.transpose() * p2->J, H12 = p12->J.transpose() * p12->J;
  EXPECT_LT((H2 - H12).cwiseAbs().maxCoeff(), 1e-9 * H12.cwiseAbs().maxCoeff());
  const Eigen::VectorXd g2 = p2->J.transpose() * p2->r, g12 = p12->J.transpose() * p12->r;
  EXPECT_LT((g2 - g12).cwiseAbs().maxCoeff(), 1e-9 * (1.0 + g12.cwiseAbs().maxCoeff()));
  EXPECT_NEAR(p2->costAtX0(), p12->costAtX0(), 1e-9 * (1.0 + p12->costAtX0()));
}

/// The prior works inside a real Ceres solve: with the prior on B and c plus the remaining residuals, the
/// optimum of B, c matches the full problem's optimum (to the accuracy of the linearisation: tiny for
/// near-consistent data).
TEST(PriorFactor, SolvesInCeresLikeTheFullProblem) {
  std::mt19937 rng(35);
  PoseManifold pm;
  const Pose A = randomPose(rng, 1.0, 2.0), B = A * randomPose(rng, 0.3, 1.0);
  const Vec3 c(0.5, 1.0, 5.0);
  auto noisy = [&](const Pose& T) { return T * randomPose(rng, 1e-3, 1e-3); };
  auto pA = posePrior(noisy(A), 10.0);
  auto rAB = relative(noisy(A.inverse() * B), 20.0);
  auto lA = landmark(A.inverse() * c + Vec3(1e-3, 0.0, -1e-3), 5.0);
  auto lB = landmark(B.inverse() * c + Vec3(-1e-3, 1e-3, 0.0), 5.0);
  auto pB = posePrior(noisy(B), 1.0);

  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Solver::Options o;
  o.function_tolerance = o.gradient_tolerance = o.parameter_tolerance = 1e-16;
  o.linear_solver_type = ceres::DENSE_QR;
  ceres::Solver::Summary summary;

  // Full problem.
  Block7 a = block(A), b = block(B);
  Vec3 cf = c;
  {
    ceres::Problem p(po);
    p.AddParameterBlock(a.data(), 7, &pm);
    p.AddParameterBlock(b.data(), 7, &pm);
    p.AddResidualBlock(pA.get(), nullptr, a.data());
    p.AddResidualBlock(rAB.get(), nullptr, a.data(), b.data());
    p.AddResidualBlock(lA.get(), nullptr, a.data(), cf.data());
    p.AddResidualBlock(lB.get(), nullptr, b.data(), cf.data());
    p.AddResidualBlock(pB.get(), nullptr, b.data());
    ceres::Solve(o, &p, &summary);
  }
  // Marginalise A at the full optimum (as a sliding window does), then solve B, c from a perturbed start.
  Marginaliser m;
  m.addParameterBlock(0, a.data(), 7, &pm);
  m.addParameterBlock(1, b.data(), 7, &pm);
  m.addParameterBlock(2, cf.data(), 3, nullptr);
  m.addResidual(pA, nullptr, {0});
  m.addResidual(rAB, nullptr, {0, 1});
  m.addResidual(lA, nullptr, {0, 2});
  auto prior = m.marginalise({0});
  ASSERT_TRUE(prior);
  Block7 b2 = block(poseFromBlock(b.data()) * randomPose(rng, 0.05, 0.1));
  Vec3 c2 = cf + Vec3(0.1, -0.1, 0.05);
  {
    ceres::Problem p(po);
    p.AddParameterBlock(b2.data(), 7, &pm);
    PriorFactor prior_factor(prior);
    p.AddResidualBlock(&prior_factor, nullptr, b2.data(), c2.data());
    p.AddResidualBlock(lB.get(), nullptr, b2.data(), c2.data());
    p.AddResidualBlock(pB.get(), nullptr, b2.data());
    ceres::Solve(o, &p, &summary);
    ASSERT_TRUE(summary.IsSolutionUsable());
  }
  EXPECT_LT((poseFromBlock(b2.data()).p - poseFromBlock(b.data()).p).norm(), 1e-7);
  EXPECT_LT(logSO3(poseFromBlock(b2.data()).q.conjugate() * poseFromBlock(b.data()).q).norm(), 1e-7);
  EXPECT_LT((c2 - cf).norm(), 1e-7);
}

}  // namespace
}  // namespace linnet
