// Triangulation on synthetic views: exact recovery without noise, bounded error with noise, and the rejection
// checks.
#include "linnet/geometry/triangulation.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/core/options.h"

namespace linnet {
namespace {

constexpr double kPi = 3.14159265358979323846;

Vec2 project(const Pose& T_W_C, const Vec3& p_W) {
  const Vec3 p_C = T_W_C.inverse() * p_W;
  return Vec2(p_C.x() / p_C.z(), p_C.y() / p_C.z());
}

/// Cameras on a ring-ish path around the origin, all looking roughly at a point cloud near `target`.
std::vector<Pose> lookingCameras(std::mt19937& rng, int n, const Vec3& target, double baseline) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Pose> cams;
  for (int k = 0; k < n; ++k) {
    const Vec3 c(baseline * u(rng), baseline * u(rng), baseline * 0.2 * u(rng));
    const Vec3 z = (target - c).normalized();
    Vec3 x = Vec3(0.0, 1.0, 0.0).cross(z);
    if (x.norm() < 1e-6) x = Vec3(1.0, 0.0, 0.0);
    x.normalize();
    const Vec3 y = z.cross(x);
    Mat3 R;
    R.col(0) = x;
    R.col(1) = y;
    R.col(2) = z;
    // A small random roll keeps the rotations generic.
    cams.emplace_back(Pose(Mat3(R * expSO3(Vec3(0.0, 0.0, 0.3 * u(rng))).toRotationMatrix()), c));
  }
  return cams;
}

TEST(Triangulation, DltRecoversPointExactlyWithoutNoise) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> depth(0.5, 20.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 p_true(u(rng), u(rng), depth(rng));
    const int n = 2 + trial % 5;
    const std::vector<Pose> cams = lookingCameras(rng, n, p_true, 0.3 + 0.5 * (u(rng) + 1.0));
    std::vector<Vec2> uv;
    for (const Pose& T : cams) uv.push_back(project(T, p_true));
    Vec3 p;
    ASSERT_TRUE(triangulateDlt(cams, uv, &p)) << "trial " << trial;
    EXPECT_LT((p - p_true).norm(), 1e-8 * (1.0 + p_true.norm())) << "trial " << trial;
    EXPECT_TRUE(allDepthsPositive(cams, p));
    EXPECT_LT(meanReprojectionError(cams, uv, p), 1e-10);
  }
}

TEST(Triangulation, TwoViewRecoversStereoDepthAndParallax) {
  // EuRoC-like stereo: 11 cm baseline along x, parallel cameras.
  const Pose T_W_C0 = Pose::identity();
  const Pose T_W_C1(Quat::Identity(), Vec3(0.11, 0.0, 0.0));
  for (double depth : {0.5, 2.0, 5.0, 20.0}) {
    const Vec3 p_true(0.3, -0.2, depth);
    Vec3 p;
    double parallax = -1.0;
    ASSERT_TRUE(
        triangulateTwoView(T_W_C0, project(T_W_C0, p_true), T_W_C1, project(T_W_C1, p_true), &p, &parallax));
    EXPECT_NEAR((p - p_true).norm(), 0.0, 1e-9 * depth);
    // The angle subtended by the baseline at the point.
    const double expected = std::acos((p_true - T_W_C0.p).normalized().dot((p_true - T_W_C1.p).normalized()));
    EXPECT_NEAR(parallax, expected, 1e-12);
    EXPECT_NEAR(depthInCamera(T_W_C0, p), depth, 1e-9 * depth);
  }
}

TEST(Triangulation, NoisyObservationsGiveBoundedErrorAndRefinementHelps) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> noise(0.0, 1.0 / 458.0);  // 1 px at EuRoC focal length
  double sum_dlt = 0.0, sum_refined = 0.0, sum_err_dlt = 0.0, sum_err_refined = 0.0;
  const int trials = 300;
  for (int trial = 0; trial < trials; ++trial) {
    const Vec3 p_true(u(rng), u(rng), 4.0 + 2.0 * u(rng));
    const std::vector<Pose> cams = lookingCameras(rng, 6, p_true, 1.0);
    std::vector<Vec2> uv;
    for (const Pose& T : cams) uv.push_back(project(T, p_true) + Vec2(noise(rng), noise(rng)));
    Vec3 p;
    ASSERT_TRUE(triangulateDlt(cams, uv, &p));
    sum_dlt += meanReprojectionError(cams, uv, p);
    sum_err_dlt += (p - p_true).norm();
    ASSERT_TRUE(refinePoint(cams, uv, &p, 10));
    sum_refined += meanReprojectionError(cams, uv, p);
    sum_err_refined += (p - p_true).norm();
  }
  // 1 px noise, ~1 m baseline at ~4 m: a few centimetres of error on average.
  EXPECT_LT(sum_err_dlt / trials, 0.05);
  EXPECT_LT(sum_err_refined / trials, 0.05);
  // Refinement minimises the (squared) reprojection error, so the mean error should not grow.
  EXPECT_LE(sum_refined, sum_dlt * 1.0001);
}

TEST(Triangulation, ParallaxHelpers) {
  const Pose a = Pose::identity();
  const Pose b(expSO3(Vec3(0.0, kPi / 2.0, 0.0)), Vec3(1.0, 0.0, 0.0));
  // Ray of a along +z; ray of b: its +z axis rotated by 90 deg about y is world +x.
  EXPECT_NEAR(rayParallaxRad(a, Vec2::Zero(), b, Vec2::Zero()), kPi / 2.0, 1e-12);
  EXPECT_NEAR(maxParallaxRad({a, a, b}, {Vec2::Zero(), Vec2(0.1, 0.0), Vec2::Zero()}), kPi / 2.0, 1e-12);
  EXPECT_EQ(maxParallaxRad({a}, {Vec2::Zero()}), 0.0);
}

TEST(Triangulation, RejectsDegenerateAndBadInputs) {
  const Pose a = Pose::identity();
  Vec3 p;
  EXPECT_FALSE(triangulateDlt({a}, {Vec2::Zero()}, &p));
  EXPECT_THROW(triangulateDlt({a, a}, {Vec2::Zero()}, &p), UsageError);
  // Parallel rays from two centres: the point is at infinity.
  const Pose b(Quat::Identity(), Vec3(0.2, 0.0, 0.0));
  EXPECT_FALSE(triangulateDlt({a, b}, {Vec2(0.1, 0.05), Vec2(0.1, 0.05)}, &p));
}

TEST(Triangulation, CheckedStatuses) {
  TriangulationOptions opt;
  const Pose a = Pose::identity();
  const Pose b(Quat::Identity(), Vec3(0.5, 0.0, 0.0));
  Vec3 p = Vec3::Constant(-7.0);
  const Vec3 p_true(0.1, 0.2, 3.0);
  EXPECT_EQ(triangulateChecked({a, b}, {project(a, p_true), project(b, p_true)}, opt, &p),
            TriangulationStatus::kOk);
  EXPECT_LT((p - p_true).norm(), 1e-9);

  EXPECT_EQ(triangulateChecked({a}, {Vec2::Zero()}, opt, &p), TriangulationStatus::kTooFewViews);

  // Far point with a tiny baseline: parallax below 0.5 deg.
  const Pose c(Quat::Identity(), Vec3(0.01, 0.0, 0.0));
  EXPECT_EQ(triangulateChecked({a, c}, {project(a, p_true), project(c, p_true)}, opt, &p),
            TriangulationStatus::kLowParallax);

  // A point behind both cameras still projects; the depth check must catch it.
  const Vec3 behind(0.1, 0.2, -3.0);
  EXPECT_EQ(triangulateChecked({a, b}, {project(a, behind), project(b, behind)}, opt, &p),
            TriangulationStatus::kBadDepth);

  // Inconsistent observations in three views: large reprojection error.
  const Pose d(Quat::Identity(), Vec3(0.0, 0.5, 0.0));
  EXPECT_EQ(
      triangulateChecked(
          {a, b, d}, {project(a, p_true), project(b, p_true), project(d, p_true) + Vec2(0.1, 0.0)}, opt, &p),
      TriangulationStatus::kHighError);
  EXPECT_STREQ(toString(TriangulationStatus::kHighError), "high reprojection error");
}

TEST(Triangulation, OptionsValidate) {
  TriangulationOptions opt;
  EXPECT_NO_THROW(validateOptions(opt, "triangulation"));
  opt.min_parallax_deg = 120.0;
  try {
    validateOptions(opt, "triangulation");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("triangulation.min_parallax_deg"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace linnet
