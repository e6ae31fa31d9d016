// FactorPool: objects reused only when nothing holds their set, and a reused factor evaluating exactly as a new one.
#include "linnet/estimator/factor_pool.h"

#include <array>
#include <memory>
#include <vector>

#include <gtest/gtest.h>

#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/factors/point_factors.h"

namespace linnet {
namespace {

Pose somePose(double a) {
  return Pose(Quat(Eigen::AngleAxisd(a, Vec3(0.3, -0.5, 0.8).normalized())), Vec3(0.1 * a, -0.2, 0.05 + a));
}

// Residual and both Jacobians of a cost function at fixed parameter values.
template <int kRows, int... kSizes>
std::vector<double> outputs(const ceres::CostFunction& f, std::array<std::vector<double>, sizeof...(kSizes)> params) {
  constexpr std::array<int, sizeof...(kSizes)> sizes{kSizes...};
  std::vector<const double*> p;
  for (const auto& v : params) p.push_back(v.data());
  std::vector<double> out(kRows);
  std::array<std::vector<double>, sizeof...(kSizes)> jac;
  std::vector<double*> jp;
  for (std::size_t k = 0; k < sizes.size(); ++k) {
    jac[k].assign(static_cast<std::size_t>(kRows * sizes[k]), 0.0);
    jp.push_back(jac[k].data());
  }
  EXPECT_TRUE(f.Evaluate(p.data(), out.data(), jp.data()));
  for (const auto& j : jac) out.insert(out.end(), j.begin(), j.end());
  return out;
}

std::vector<double> poseBlock(const Pose& T) {
  return {T.p.x(), T.p.y(), T.p.z(), T.q.x(), T.q.y(), T.q.z(), T.q.w()};
}

TEST(FactorPool, ReusesASetOnlyWhenNothingHoldsIt) {
  FactorPool<PointStereoFactor> pool;
  pool.begin();
  std::shared_ptr<PointStereoFactor> a = pool.make(Vec2(0.1, 0.2), Vec2(0.05, 0.2), Pose(), somePose(0.1), 300.0);
  const PointStereoFactor* first = a.get();
  // Held: the next set gets new objects, and the held one keeps its values.
  pool.begin();
  std::shared_ptr<PointStereoFactor> b = pool.make(Vec2(-0.3, 0.1), Vec2(-0.35, 0.1), Pose(), somePose(0.2), 200.0);
  EXPECT_NE(b.get(), first);
  EXPECT_EQ(a->uvLeft(), Vec2(0.1, 0.2));
  EXPECT_DOUBLE_EQ(a->sqrtInfo(), 300.0);
  // Released: the next set reuses the last set's objects, in order.
  const PointStereoFactor* second = b.get();
  a.reset();
  b.reset();
  pool.begin();
  std::shared_ptr<PointStereoFactor> c = pool.make(Vec2(0.4, -0.1), Vec2(0.3, -0.1), Pose(), somePose(0.3), 100.0);
  EXPECT_EQ(c.get(), second);
  EXPECT_EQ(c->uvLeft(), Vec2(0.4, -0.1));
  EXPECT_EQ(pool.capacity(), 1u);
  // A pointer to a base class shares the set as well.
  std::shared_ptr<ceres::CostFunction> base = c;
  c.reset();
  pool.begin();
  EXPECT_NE(pool.make(Vec2(0.0, 0.0), Vec2(0.0, 0.0), Pose(), somePose(0.3), 1.0).get(), second);
}

TEST(FactorPool, ReusedFactorsEvaluateAsNewOnes) {
  const Pose T_B_C0 = somePose(0.05), T_B_C1 = somePose(0.07);
  const std::vector<double> Ti = poseBlock(somePose(0.4)), Tj = poseBlock(somePose(0.6));
  FactorPool<PointReprojectionFactor> points;
  FactorPool<PointStereoFactor> stereo;
  FactorPool<LineReprojectionFactor> lines;
  const Vec6 L = (Vec6() << 0.3, -1.2, 0.4, 0.6, 0.2, -0.3).finished();
  const std::vector<double> line(L.data(), L.data() + 6);
  for (int round = 0; round < 3; ++round) {
    points.begin();
    stereo.begin();
    lines.begin();
    const double k = 0.1 * round;
    const Vec2 u(0.1 + k, -0.2), v(0.12 + k, -0.18), s(-0.2, 0.1 + k), e(0.3, 0.15 - k);
    const auto p = points.make(u, v, T_B_C0, T_B_C1, 300.0 + round);
    const PointReprojectionFactor p_new(u, v, T_B_C0, T_B_C1, 300.0 + round);
    EXPECT_EQ((outputs<2, 7, 7, 1>(*p, {Ti, Tj, {0.5}})), (outputs<2, 7, 7, 1>(p_new, {Ti, Tj, {0.5}})));
    const auto q = stereo.make(u, v, T_B_C0, T_B_C1, 200.0 + round);
    const PointStereoFactor q_new(u, v, T_B_C0, T_B_C1, 200.0 + round);
    EXPECT_EQ((outputs<2, 1>(*q, {std::vector<double>{0.5}})), (outputs<2, 1>(q_new, {std::vector<double>{0.5}})));
    // The line factor keeps the terms of the last pose it saw, which depend on its extrinsics too: a reused one, at
    // the same pose with other extrinsics, must not answer from the old ones.
    const Pose T_B_C = somePose(0.05 + 0.1 * round);
    const auto l = lines.make(s, e, T_B_C, 250.0 + round);
    const LineReprojectionFactor l_new(s, e, T_B_C, 250.0 + round);
    EXPECT_EQ((outputs<2, 7, 6>(*l, {Ti, line})), (outputs<2, 7, 6>(l_new, {Ti, line})));
    std::array<double, 2> r_pooled{}, r_new{};
    const double* params[2] = {Ti.data(), line.data()};
    ASSERT_TRUE(l->evaluateTangentSpace(params, r_pooled.data(), nullptr));
    ASSERT_TRUE(l_new.evaluateTangentSpace(params, r_new.data(), nullptr));
    EXPECT_EQ(r_pooled, r_new);
  }
  EXPECT_EQ(points.capacity(), 1u);
  EXPECT_EQ(lines.capacity(), 1u);
}

}  // namespace
}  // namespace linnet
