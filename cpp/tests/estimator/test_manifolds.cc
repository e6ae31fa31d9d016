// PoseManifold: Ceres' manifold invariants, Plus/Minus semantics, and the tangent -> ambient Jacobian helper.
#include <random>

#include <ceres/manifold_test_utils.h>
#include <gtest/gtest.h>

#include "linnet/estimator/manifolds.h"

namespace linnet {
namespace {

using Vector7 = Eigen::Matrix<double, 7, 1>;

Vector7 randomPoseBlock(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Vector7 x;
  Quat q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  x << 3.0 * n(rng), 3.0 * n(rng), 3.0 * n(rng), q.x(), q.y(), q.z(), q.w();
  return x;
}

TEST(PoseManifold, CeresInvariantsHoldAtRandomPoints) {
  using namespace ceres;  // NOLINT: the invariant macro names ceres' matchers and Vector unqualified
  std::mt19937 rng(42);
  std::normal_distribution<double> n(0.0, 1.0);
  const PoseManifold manifold;
  for (int trial = 0; trial < 20; ++trial) {
    const Vector7 xv = randomPoseBlock(rng);
    ceres::Vector x = xv;
    ceres::Vector delta(6);
    for (int i = 0; i < 6; ++i) delta[i] = 0.5 * n(rng);
    // y = Plus(x, small tangent step): Plus(x, Minus(y, x)) then reproduces y with the same quaternion sign.
    ceres::Vector step(6);
    for (int i = 0; i < 6; ++i) step[i] = 0.8 * n(rng);
    ceres::Vector y(7);
    ASSERT_TRUE(manifold.Plus(x.data(), step.data(), y.data()));
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
  }
}

TEST(PoseManifold, PlusIsRightPerturbationAndPositionInWorld) {
  const PoseManifold manifold;
  const Quat q = Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()));
  const Vec3 p(1.0, -2.0, 0.5);
  double x[7];
  setPose(Pose(q, p), x);
  const Vec3 dp(0.1, 0.2, -0.3), dth(0.05, -0.02, 0.3);
  double delta[6] = {dp.x(), dp.y(), dp.z(), dth.x(), dth.y(), dth.z()};
  double out[7];
  ASSERT_TRUE(manifold.Plus(x, delta, out));
  const Pose T = poseFromBlock(out);
  EXPECT_LT((T.p - (p + dp)).norm(), 1e-15);
  EXPECT_LT(T.q.angularDistance(q * expSO3(dth)), 1e-12);
  double back[6];
  ASSERT_TRUE(manifold.Minus(out, x, back));
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(back[i], delta[i], 1e-12);
}

TEST(PoseManifold, BlockAccessorsRoundTrip) {
  const Pose T(Quat(Eigen::AngleAxisd(-1.2, Vec3(0, 1, 1).normalized())), Vec3(4, 5, 6));
  double x[7];
  setPose(T, x);
  EXPECT_EQ(posePosition(x), T.p);
  EXPECT_LT(poseRotation(x).angularDistance(T.q), 1e-15);
  // Eigen coeffs order (x, y, z, w) in the block.
  EXPECT_DOUBLE_EQ(x[6], T.q.w());
  EXPECT_DOUBLE_EQ(x[3], T.q.x());
  EXPECT_LT((poseFromBlock(x).matrix() - T.matrix()).norm(), 1e-14);
}

TEST(PoseManifold, TangentToAmbientTimesPlusJacobianIsTangent) {
  std::mt19937 rng(7);
  const PoseManifold manifold;
  for (int trial = 0; trial < 10; ++trial) {
    const Vector7 x = randomPoseBlock(rng);
    const Eigen::Matrix<double, 4, 6> Jt = Eigen::Matrix<double, 4, 6>::Random();
    Eigen::Matrix<double, 4, 7, Eigen::RowMajor> Ja;
    tangentToAmbientPose<4>(Jt, x.data(), Ja.data());
    Eigen::Matrix<double, 7, 6, Eigen::RowMajor> P;
    ASSERT_TRUE(manifold.PlusJacobian(x.data(), P.data()));
    EXPECT_LT((Ja * P - Jt).norm(), 1e-14);
    // Row vector and dynamic row count variants.
    const Eigen::Matrix<double, 1, 6> J1 = Jt.row(0);
    Eigen::Matrix<double, 1, 7> Ja1;
    tangentToAmbientPose<1>(J1, x.data(), Ja1.data());
    EXPECT_LT((Ja1 * P - J1).norm(), 1e-14);
    const Eigen::Matrix<double, Eigen::Dynamic, 6> Jd = Jt;
    Eigen::Matrix<double, Eigen::Dynamic, 7, Eigen::RowMajor> Jad(4, 7);
    tangentToAmbientPose<Eigen::Dynamic>(Jd, x.data(), Jad.data());
    EXPECT_LT((Jad * P - Jt).norm(), 1e-14);
    // The MinusJacobian is the same linear map: J_ambient == J_tangent * MinusJacobian.
    Eigen::Matrix<double, 6, 7, Eigen::RowMajor> M;
    ASSERT_TRUE(manifold.MinusJacobian(x.data(), M.data()));
    EXPECT_LT((Jt * M - Ja).norm(), 1e-14);
  }
}

}  // namespace
}  // namespace linnet
