// ImuFactor: zero residual on the true motion, Jacobians through the shared checker, and a small Ceres solve.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <random>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "imu/imu_test_motion.h"
#include "linnet/core/error.h"
#include "linnet/estimator/factors/imu_factor.h"
#include "linnet/estimator/manifolds.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

constexpr Timestamp kMs = 1'000'000;

struct Blocks {
  double pose_i[7], sb_i[9], pose_j[7], sb_j[9];
  std::vector<double*> ptrs() { return {pose_i, sb_i, pose_j, sb_j}; }
};

void setSpeedBias(const ImuState& s, double* sb) {
  Eigen::Map<Vec3> v(sb), ba(sb + 3), bg(sb + 6);
  v = s.v_W;
  ba = s.b_a;
  bg = s.b_g;
}

Blocks blocksFrom(const ImuState& si, const ImuState& sj) {
  Blocks b;
  setPose(si.T_W_B, b.pose_i);
  setPose(sj.T_W_B, b.pose_j);
  setSpeedBias(si, b.sb_i);
  setSpeedBias(sj, b.sb_j);
  return b;
}

TEST(ImuFactor, ResidualVanishesOnTheTrueMotion) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  const Vec3 b_a(0.05, -0.1, 0.08), b_g(0.004, -0.01, 0.02);
  // Linearised at zero bias: the factor must correct to the state's biases to first order.
  for (const double s : {1.0, 0.9}) {
    const Vec3 lin_scale = Vec3::Constant(s);
    const auto pre =
        std::make_shared<Preintegration>(m.samples(200 * kMs, 700 * kMs, 5 * kMs, b_a, b_g), noise,
                                         b_a.cwiseProduct(lin_scale), b_g.cwiseProduct(lin_scale));
    const ImuFactor f(pre, noise.gravityVector());
    Blocks b = blocksFrom(m.state(200 * kMs, b_a, b_g), m.state(700 * kMs, b_a, b_g));
    const Vec15 r = f.unweightedResidual(b.pose_i, b.sb_i, b.pose_j, b.sb_j);
    std::printf("  true motion, linearised at %.1f x bias: |r_p| %.3g |r_theta| %.3g |r_v| %.3g\n",
                lin_scale.x(), r.segment<3>(0).norm(), r.segment<3>(3).norm(), r.segment<3>(6).norm());
    EXPECT_LT(r.segment<3>(0).norm(), 1e-5);
    EXPECT_LT(r.segment<3>(3).norm(), 1e-5);
    EXPECT_LT(r.segment<3>(6).norm(), 2e-5);
    EXPECT_LT(r.tail<6>().norm(), 1e-15);
    // Whitened residual = S r.
    Vec15 rw;
    const double* params[4] = {b.pose_i, b.sb_i, b.pose_j, b.sb_j};
    ASSERT_TRUE(f.Evaluate(params, rw.data(), nullptr));
    EXPECT_LT((rw - f.sqrtInformation() * r).norm(), 1e-9 * (1.0 + rw.norm()));
  }
}

TEST(ImuFactor, SqrtInformationWhitensTheCovariance) {
  const testing::SmoothMotion m;
  const auto pre = std::make_shared<Preintegration>(m.samples(0, 300 * kMs, 5 * kMs), ImuNoise(),
                                                    Vec3::Zero(), Vec3::Zero());
  const ImuFactor f(pre, 9.81);
  const Mat15& S = f.sqrtInformation();
  EXPECT_TRUE(S.isUpperTriangular(1e-12));
  const Mat15 white = S * pre->covariance() * S.transpose();
  EXPECT_LT((white - Mat15::Identity()).norm(), 1e-6);
}

TEST(ImuFactor, JacobiansPassTheCheckerAtRandomStates) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  std::mt19937 rng(2024);
  std::normal_distribution<double> n(0.0, 1.0);
  auto rnd3 = [&](double s) { return Vec3(s * n(rng), s * n(rng), s * n(rng)); };
  const PoseManifold pose_manifold;
  double worst = 0.0;
  for (int trial = 0; trial < 10; ++trial) {
    const Vec3 b_a_lin = rnd3(0.1), b_g_lin = rnd3(0.01);
    const Timestamp t0 = (100 + 37 * trial) * kMs;
    const auto pre = std::make_shared<Preintegration>(
        m.samples(t0, t0 + (100 + 40 * trial) * kMs, 5 * kMs, rnd3(0.1), rnd3(0.01)), noise, b_a_lin,
        b_g_lin);
    const ImuFactor f(pre, noise.gravityVector());
    // Random states (not consistent with the measurements: residuals far from zero), biases away from b_lin.
    ImuState si, sj;
    si.T_W_B = Pose(expSO3(rnd3(1.5)), rnd3(2.0));
    sj.T_W_B = Pose(si.T_W_B.q * expSO3(rnd3(0.3)), si.T_W_B.p + rnd3(0.5));
    si.v_W = rnd3(1.0);
    sj.v_W = rnd3(1.0);
    si.b_a = b_a_lin + rnd3(0.05);
    si.b_g = b_g_lin + rnd3(0.005);
    sj.b_a = rnd3(0.1);
    sj.b_g = rnd3(0.01);
    Blocks b = blocksFrom(si, sj);
    // Whitened residuals reach 1e5 here, so round-off in the differences is ~1e-6 absolute: step 1e-5, tol
    // 1e-5.
    const auto res =
        testing::checkJacobians(f, b.ptrs(), {&pose_manifold, nullptr, &pose_manifold, nullptr}, 1e-5);
    worst = std::max(worst, res.maxRelError());
    EXPECT_TRUE(res.ok(1e-5)) << res.describe(1e-5, true);
  }
  std::printf("  ImuFactor Jacobians: worst relative error over 10 random states %.3g\n", worst);
}

TEST(ImuFactor, JacobiansPassTheCheckerOnShortIntervalsNearTheSolution) {
  // One IMU step (5 ms) and one camera frame (50 ms): information up to ~1e8, states near the true motion as
  // in a running estimator.
  const testing::SmoothMotion m;
  const ImuNoise noise;
  std::mt19937 rng(77);
  std::normal_distribution<double> n(0.0, 1.0);
  auto rnd3 = [&](double s) { return Vec3(s * n(rng), s * n(rng), s * n(rng)); };
  const PoseManifold pm;
  const Vec3 b_a(0.08, -0.05, 0.02), b_g(0.01, -0.004, 0.006);
  for (const Timestamp duration : {5 * kMs, 50 * kMs}) {
    const Timestamp t0 = 250 * kMs, t1 = t0 + duration;
    const auto pre = std::make_shared<Preintegration>(m.samples(t0, t1, 5 * kMs, b_a, b_g), noise,
                                                      b_a + rnd3(0.02), b_g + rnd3(0.002));
    const ImuFactor f(pre, noise.gravityVector());
    // Perturbations scaled with the interval keep the whitened residual moderate (central differences lose
    // ~eps |r| / h to round-off, so a residual of 1e7 would swamp any check).
    const double scale = toSeconds(duration) / 0.05;
    const Vec3 b_a_i = b_a + rnd3(0.01), b_g_i = b_g + rnd3(0.001);
    ImuState si = m.state(t0, b_a_i, b_g_i), sj = m.state(t1, b_a_i, b_g_i);
    sj.T_W_B = Pose(sj.T_W_B.q * expSO3(rnd3(1e-3 * scale)), sj.T_W_B.p + rnd3(1e-3 * scale * scale));
    sj.v_W += rnd3(1e-3 * scale);
    Blocks b = blocksFrom(si, sj);
    const auto res = testing::checkJacobians(f, b.ptrs(), {&pm, nullptr, &pm, nullptr}, 1e-6);
    std::printf("  ImuFactor over %.0f ms: worst relative Jacobian error %.3g (|whitened r| %.3g)\n",
                toSeconds(duration) * 1e3, res.maxRelError(), res.residuals.norm());
    EXPECT_TRUE(res.ok(1e-5)) << res.describe(1e-5, true);
  }
}

TEST(ImuFactor, SolvesForTheSecondStateGivenTheFirst) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  const Vec3 b_a(0.03, -0.02, 0.05), b_g(0.002, 0.001, -0.003);
  const auto pre = std::make_shared<Preintegration>(m.samples(0, 600 * kMs, 5 * kMs, b_a, b_g), noise,
                                                    Vec3::Zero(), Vec3::Zero());
  const ImuState si = m.state(0, b_a, b_g), sj = m.state(600 * kMs, b_a, b_g);
  Blocks b = blocksFrom(si, sj);
  // Perturb the unknown second state.
  const PoseManifold pm;
  double delta[6] = {0.3, -0.2, 0.1, 0.1, -0.2, 0.15};
  double perturbed[7];
  pm.Plus(b.pose_j, delta, perturbed);
  std::copy(perturbed, perturbed + 7, b.pose_j);
  b.sb_j[0] += 0.5;
  b.sb_j[4] += 0.1;

  ceres::Problem problem;
  problem.AddResidualBlock(new ImuFactor(pre, noise.gravityVector()), nullptr, b.pose_i, b.sb_i, b.pose_j,
                           b.sb_j);
  problem.SetManifold(b.pose_i, new PoseManifold);
  problem.SetManifold(b.pose_j, new PoseManifold);
  problem.SetParameterBlockConstant(b.pose_i);
  problem.SetParameterBlockConstant(b.sb_i);
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = 20;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  const Pose Tj = poseFromBlock(b.pose_j);
  EXPECT_LT((Tj.p - sj.T_W_B.p).norm(), 1e-4);
  EXPECT_LT(Tj.q.angularDistance(sj.T_W_B.q), 1e-4);
  EXPECT_LT((Eigen::Map<const Vec3>(b.sb_j) - sj.v_W).norm(), 2e-4);
  EXPECT_LT((Eigen::Map<const Vec3>(b.sb_j + 3) - b_a).norm(), 1e-9);
  EXPECT_LE(summary.iterations.size(), 10u);
}

TEST(ImuFactor, RejectsEmptyPreintegration) {
  const auto empty = std::make_shared<Preintegration>(ImuNoise(), Vec3::Zero(), Vec3::Zero());
  EXPECT_THROW(ImuFactor(empty, 9.81), UsageError);
  EXPECT_THROW(ImuFactor(std::shared_ptr<const Preintegration>(), 9.81), UsageError);
  ImuNoise silent;
  silent.acc_noise_density = silent.gyr_noise_density = silent.acc_random_walk = silent.gyr_random_walk = 0.0;
  PreintegrationOptions no_integration_noise;
  no_integration_noise.integration_noise = 0.0;
  const Preintegration zero({{0, Vec3(0, 0, 9.81), Vec3::Zero()}, {5 * kMs, Vec3(0, 0, 9.81), Vec3::Zero()}},
                            silent, Vec3::Zero(), Vec3::Zero(), no_integration_noise);
  EXPECT_THROW(ImuFactor(zero, silent.gravityVector()), UsageError);
}

}  // namespace
}  // namespace linnet
