// Rest priors (zero-velocity update): the zero-velocity and no-motion factors' residuals and Jacobians against
// numeric differences through the manifolds (the shared checker), and the checker rejecting a wrong one.
#include "linnet/estimator/factors/zero_velocity_factor.h"

#include <array>
#include <random>

#include <gtest/gtest.h>

#include "linnet/core/pose.h"
#include "linnet/estimator/manifolds.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

std::array<double, 7> randomPoseBlock(std::mt19937& rng, double angle) {
  std::normal_distribution<double> n(0.0, 1.0);
  std::array<double, 7> b{};
  setPose(Pose(expSO3(angle * Vec3(n(rng), n(rng), n(rng))), Vec3(n(rng), n(rng), n(rng))), b.data());
  return b;
}

TEST(RestFactors, ZeroVelocityResidualAndJacobian) {
  const ZeroVelocityFactor f(0.01);
  std::array<double, 9> sb = {0.02, -0.01, 0.005, 0.1, 0.2, 0.3, 0.01, 0.02, 0.03};
  const double* p[1] = {sb.data()};
  double r[3];
  ASSERT_TRUE(f.Evaluate(p, r, nullptr));
  EXPECT_NEAR(r[0], 2.0, 1e-12);
  EXPECT_NEAR(r[1], -1.0, 1e-12);
  EXPECT_NEAR(r[2], 0.5, 1e-12);
  EXPECT_TRUE(testing::jacobiansMatch(f, {sb.data()}, {nullptr}, 1e-6));
}

TEST(RestFactors, NoMotionResidualAndJacobians) {
  std::mt19937 rng(31);
  const PoseManifold pm;
  const NoMotionFactor f(0.001, 0.001);
  for (int trial = 0; trial < 50; ++trial) {
    auto bi = randomPoseBlock(rng, 1.0);
    // j near i (rest), and far from it (the Jacobian must hold anywhere).
    std::array<double, 7> bj{};
    const double spread = trial % 2 == 0 ? 0.01 : 1.0;
    setPose(poseFromBlock(bi.data()) * Pose(expSO3(spread * Vec3(0.3, -0.2, 0.5)), spread * Vec3(1, 2, 3)), bj.data());
    ASSERT_TRUE(testing::jacobiansMatch(f, {bi.data(), bj.data()}, {&pm, &pm}, 1e-6)) << "trial " << trial;
  }
  // Same pose: zero residual.
  auto b = randomPoseBlock(rng, 1.0);
  const double* p[2] = {b.data(), b.data()};
  double r[6];
  ASSERT_TRUE(f.Evaluate(p, r, nullptr));
  for (double v : r) EXPECT_NEAR(v, 0.0, 1e-9);
}

/// The no-motion factor with its rotation Jacobian of block i scaled: the checker must reject it.
class CorruptNoMotion : public ceres::SizedCostFunction<6, 7, 7> {
 public:
  bool Evaluate(double const* const* p, double* r, double** J) const override {
    if (!f_.Evaluate(p, r, J)) return false;
    if (J != nullptr && J[0] != nullptr) J[0][3 * 7 + 4] *= 1.001;
    return true;
  }

 private:
  NoMotionFactor f_{0.001, 0.001};
};

TEST(RestFactors, CheckerRejectsAWrongNoMotionJacobian) {
  std::mt19937 rng(32);
  const PoseManifold pm;
  auto bi = randomPoseBlock(rng, 1.0), bj = randomPoseBlock(rng, 1.0);
  EXPECT_FALSE(testing::checkJacobians(CorruptNoMotion(), {bi.data(), bj.data()}, {&pm, &pm}).ok(1e-6));
}

}  // namespace
}  // namespace linnet
