// Point residuals: analytic Jacobians against the shared checker (random poses, depths 0.5-20 m), the checker
// catching a wrong Jacobian at the tolerance used here, the pixel error helper, and a small bundle
// adjustment.
#include "linnet/estimator/factors/point_factors.h"

#include <array>
#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include <ceres/ceres.h>
#include <gtest/gtest.h>

#include "linnet/estimator/manifolds.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

constexpr double kFocal = 458.0;  // EuRoC cam0, pixels
constexpr double kTol = 1e-6;     // checker's relative tolerance
const double kSqrtInfo = pointSqrtInformation(kFocal);

Pose poseFromRowMajor(const double m[12]) {
  Mat3 R;
  R << m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10];
  return Pose(R, Vec3(m[3], m[7], m[11]));
}

// EuRoC MAV extrinsics (sensor.yaml T_BS of cam0 and cam1).
Pose eurocTBC0() {
  const double m[12] = {0.0148655429818,  -0.999880929698,  0.00414029679422, -0.0216401454975,
                        0.999557249008,   0.0149672133247,  0.025715529948,   -0.064676986768,
                        -0.0257744366974, 0.00375618835797, 0.999660727178,   0.00981073058949};
  return poseFromRowMajor(m);
}
Pose eurocTBC1() {
  const double m[12] = {0.0125552670891,  -0.999755099723, 0.0182237714554, -0.0198435579556,
                        0.999598781151,   0.0130119051815, 0.0251588363115, 0.0453689425024,
                        -0.0253898008918, 0.0179005838253, 0.999517347078,  0.00786212447038};
  return poseFromRowMajor(m);
}

Vec2 projectInto(const Pose& T_W_C, const Vec3& p_W) {
  const Vec3 p = T_W_C.inverse() * p_W;
  return Vec2(p.x() / p.z(), p.y() / p.z());
}

Quat randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Quat(n(rng), n(rng), n(rng), n(rng)).normalized();
}

struct Scenario {
  Pose T_W_Bi, T_W_Bj;
  double inv_depth = 1.0;
  Vec2 uv_host, uv_target;
  Vec3 p_W;
};

/// Random host pose, a point 0.5-20 m in front of the host camera, a target frame moved by up to 0.3 rad /
/// 0.4 m that still sees the point in front. Observations are exact plus `noise` (normalised units).
Scenario randomScenario(std::mt19937& rng, const Pose& T_B_Ch, const Pose& T_B_Ct, double noise) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(0.5, 20.0);
  std::normal_distribution<double> nz(0.0, noise);
  for (;;) {
    Scenario s;
    s.T_W_Bi = Pose(randomRotation(rng), Vec3(5.0 * u(rng), 5.0 * u(rng), 2.0 * u(rng)));
    s.T_W_Bj =
        s.T_W_Bi * Pose(expSO3(0.3 * Vec3(u(rng), u(rng), u(rng))), 0.4 * Vec3(u(rng), u(rng), u(rng)));
    const double d = depth(rng);
    s.uv_host = Vec2(0.5 * u(rng), 0.4 * u(rng));
    s.inv_depth = 1.0 / d;
    s.p_W = (s.T_W_Bi * T_B_Ch) * (Vec3(s.uv_host.x(), s.uv_host.y(), 1.0) * d);
    const Vec3 p_Ct = (s.T_W_Bj * T_B_Ct).inverse() * s.p_W;
    if (p_Ct.z() < 0.2) continue;
    s.uv_target = Vec2(p_Ct.x() / p_Ct.z(), p_Ct.y() / p_Ct.z()) + Vec2(nz(rng), nz(rng));
    return s;
  }
}

void toBlock(const Pose& T, double* block) { setPose(T, block); }

TEST(PointFactors, ReprojectionJacobiansSameCamera) {
  std::mt19937 rng(1);
  const PoseManifold pose_manifold;
  for (int trial = 0; trial < 100; ++trial) {
    const Scenario s = randomScenario(rng, eurocTBC0(), eurocTBC0(), 2.0 / kFocal);
    const PointReprojectionFactor f(s.uv_host, s.uv_target, eurocTBC0(), eurocTBC0(), kSqrtInfo);
    double pi[7], pj[7], rho[1] = {s.inv_depth};
    toBlock(s.T_W_Bi, pi);
    toBlock(s.T_W_Bj, pj);
    ASSERT_TRUE(testing::jacobiansMatch(f, {pi, pj, rho}, {&pose_manifold, &pose_manifold, nullptr}, kTol))
        << "trial " << trial << " depth " << 1.0 / s.inv_depth;
  }
}

TEST(PointFactors, ReprojectionJacobiansLeftToRight) {
  std::mt19937 rng(2);
  const PoseManifold pose_manifold;
  for (int trial = 0; trial < 100; ++trial) {
    const Scenario s = randomScenario(rng, eurocTBC0(), eurocTBC1(), 2.0 / kFocal);
    const PointReprojectionFactor f(s.uv_host, s.uv_target, eurocTBC0(), eurocTBC1(), kSqrtInfo);
    double pi[7], pj[7], rho[1] = {s.inv_depth};
    toBlock(s.T_W_Bi, pi);
    toBlock(s.T_W_Bj, pj);
    ASSERT_TRUE(testing::jacobiansMatch(f, {pi, pj, rho}, {&pose_manifold, &pose_manifold, nullptr}, kTol))
        << "trial " << trial;
  }
}

TEST(PointFactors, StereoJacobianAndZeroResidualAtTruth) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(0.5, 20.0);
  const Pose T_C1_C0 = eurocTBC1().inverse() * eurocTBC0();
  for (int trial = 0; trial < 100; ++trial) {
    const double d = depth(rng);
    const Vec2 uv_l(0.5 * u(rng), 0.4 * u(rng));
    const Vec3 p_C1 = T_C1_C0 * (Vec3(uv_l.x(), uv_l.y(), 1.0) * d);
    const Vec2 uv_r(p_C1.x() / p_C1.z(), p_C1.y() / p_C1.z());
    const PointStereoFactor exact(uv_l, uv_r, eurocTBC0(), eurocTBC1(), kSqrtInfo);
    double rho[1] = {1.0 / d};
    const double* params[1] = {rho};
    double r[2];
    ASSERT_TRUE(exact.Evaluate(params, r, nullptr));
    EXPECT_LT(std::hypot(r[0], r[1]), 1e-9);
    // Jacobian away from the truth (noisy right observation, perturbed depth).
    const PointStereoFactor noisy(uv_l, uv_r + Vec2(1.0, -2.0) / kFocal, eurocTBC0(), eurocTBC1(), kSqrtInfo);
    rho[0] *= 1.0 + 0.3 * u(rng);
    ASSERT_TRUE(testing::jacobiansMatch(noisy, {rho}, {}, kTol)) << "trial " << trial;
  }
}

/// Wraps a factor and corrupts one Jacobian entry by a relative amount: the checker must reject it.
class CorruptedFactor : public ceres::SizedCostFunction<2, 7, 7, 1> {
 public:
  CorruptedFactor(const PointReprojectionFactor& f, int block, int entry, double rel)
      : f_(f), block_(block), entry_(entry), rel_(rel) {}
  bool Evaluate(double const* const* p, double* r, double** J) const override {
    if (!f_.Evaluate(p, r, J)) return false;
    if (J != nullptr && J[block_] != nullptr) J[block_][entry_] *= 1.0 + rel_;
    return true;
  }

 private:
  const PointReprojectionFactor& f_;
  int block_, entry_;
  double rel_;
};

TEST(PointFactors, CheckerRejectsSlightlyWrongJacobians) {
  std::mt19937 rng(4);
  const PoseManifold pose_manifold;
  const Scenario s = randomScenario(rng, eurocTBC0(), eurocTBC1(), 1.0 / kFocal);
  const PointReprojectionFactor f(s.uv_host, s.uv_target, eurocTBC0(), eurocTBC1(), kSqrtInfo);
  double pi[7], pj[7], rho[1] = {s.inv_depth};
  toBlock(s.T_W_Bi, pi);
  toBlock(s.T_W_Bj, pj);
  ASSERT_TRUE(testing::checkJacobians(f, {pi, pj, rho}, {&pose_manifold, &pose_manifold, nullptr}).ok(kTol));
  // A 1e-3 relative error in a position, a rotation or the inverse-depth entry must fail at kTol.
  for (auto [block, entry] : {std::pair{0, 0}, std::pair{1, 4}, std::pair{0, 12}, std::pair{2, 1}}) {
    const CorruptedFactor bad(f, block, entry, 1e-3);
    EXPECT_FALSE(
        testing::checkJacobians(bad, {pi, pj, rho}, {&pose_manifold, &pose_manifold, nullptr}).ok(kTol))
        << "block " << block << " entry " << entry;
  }
}

TEST(PointFactors, PixelErrorMatchesResidual) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 50; ++trial) {
    const Pose T_B_Ct = trial % 2 == 0 ? eurocTBC0() : eurocTBC1();
    const Scenario s = randomScenario(rng, eurocTBC0(), T_B_Ct, 3.0 / kFocal);
    const PointReprojectionFactor f(s.uv_host, s.uv_target, eurocTBC0(), T_B_Ct, kSqrtInfo);
    Vec2 r;
    ASSERT_TRUE(f.evaluateTangent(s.T_W_Bi, s.T_W_Bj, s.inv_depth, &r, nullptr, nullptr, nullptr));
    const double px = pointReprojectionErrorPx(s.uv_host, s.uv_target, eurocTBC0(), T_B_Ct, s.T_W_Bi,
                                               s.T_W_Bj, s.inv_depth, kFocal);
    EXPECT_NEAR(px, r.norm() / kSqrtInfo * kFocal, 1e-9);
    // Exact observation: zero error.
    const Vec2 uv_exact = projectInto(s.T_W_Bj * T_B_Ct, s.p_W);
    EXPECT_LT(pointReprojectionErrorPx(s.uv_host, uv_exact, eurocTBC0(), T_B_Ct, s.T_W_Bi, s.T_W_Bj,
                                       s.inv_depth, kFocal),
              1e-8);
  }
  // Negative inverse depth or a point behind the target camera: infinite error (rejected as an outlier).
  EXPECT_TRUE(std::isinf(
      pointReprojectionErrorPx(Vec2::Zero(), Vec2::Zero(), Pose(), Pose(), Pose(), Pose(), -1.0, kFocal)));
  const Pose behind(expSO3(Vec3(0.0, 3.14159265358979, 0.0)), Vec3(0.0, 0.0, 0.0));
  EXPECT_TRUE(std::isinf(
      pointReprojectionErrorPx(Vec2::Zero(), Vec2::Zero(), Pose(), Pose(), Pose(), behind, 0.5, kFocal)));
}

/// A small stereo bundle adjustment with all three kinds: poses 1..N-1 and inverse depths perturbed, pose 0
/// fixed; noise-free observations, so the solve must return the truth.
TEST(PointFactors, BundleAdjustmentWithAllThreeKindsRecoversTruth) {
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Pose T_B_C0 = eurocTBC0(), T_B_C1 = eurocTBC1();
  const int n_frames = 5, n_points = 40;
  std::vector<Pose> truth;
  for (int k = 0; k < n_frames; ++k)
    truth.push_back(Pose(expSO3(Vec3(0.05 * k, -0.03 * k, 0.02 * k)), Vec3(0.2 * k, 0.05 * k, -0.03 * k)));
  // Points in front of the first left camera (camera z is roughly body x for EuRoC), 2-8 m deep.
  std::vector<Vec3> points;
  for (int p = 0; p < n_points; ++p)
    points.push_back((truth[0] * T_B_C0) * Vec3(1.5 * u(rng), 1.0 * u(rng), 5.0 + 3.0 * u(rng)));

  std::vector<std::array<double, 7>> poses(n_frames);
  for (int k = 0; k < n_frames; ++k) {
    Pose T = truth[k];
    if (k > 0) T = T * Pose(expSO3(0.02 * Vec3(u(rng), u(rng), u(rng))), 0.05 * Vec3(u(rng), u(rng), u(rng)));
    setPose(T, poses[k].data());
  }
  std::vector<double> rho(n_points);
  std::vector<Vec2> uv_host(n_points);
  ceres::Problem::Options popts;
  popts.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(popts);
  PoseManifold pose_manifold;
  for (auto& p : poses) problem.AddParameterBlock(p.data(), 7, &pose_manifold);
  problem.SetParameterBlockConstant(poses[0].data());
  for (int p = 0; p < n_points; ++p) {
    uv_host[p] = projectInto(truth[0] * T_B_C0, points[p]);
    rho[p] = (1.0 / ((truth[0] * T_B_C0).inverse() * points[p]).z()) * (1.0 + 0.2 * u(rng));
    problem.AddResidualBlock(new PointStereoFactor(uv_host[p], projectInto(truth[0] * T_B_C1, points[p]),
                                                   T_B_C0, T_B_C1, kSqrtInfo),
                             nullptr, &rho[p]);
    for (int k = 1; k < n_frames; ++k) {
      problem.AddResidualBlock(
          new PointReprojectionFactor(uv_host[p], projectInto(truth[k] * T_B_C0, points[p]), T_B_C0, T_B_C0,
                                      kSqrtInfo),
          new ceres::HuberLoss(1.0), poses[0].data(), poses[k].data(), &rho[p]);
      problem.AddResidualBlock(
          new PointReprojectionFactor(uv_host[p], projectInto(truth[k] * T_B_C1, points[p]), T_B_C0, T_B_C1,
                                      kSqrtInfo),
          new ceres::HuberLoss(1.0), poses[0].data(), poses[k].data(), &rho[p]);
    }
  }
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_SCHUR;
  options.max_num_iterations = 50;
  options.function_tolerance = 1e-14;
  options.gradient_tolerance = 1e-14;
  options.parameter_tolerance = 1e-14;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
  for (int k = 1; k < n_frames; ++k) {
    const Pose est = poseFromBlock(poses[k].data());
    EXPECT_LT((est.p - truth[k].p).norm(), 1e-7) << "frame " << k;
    EXPECT_LT(logSO3(est.q.conjugate() * truth[k].q).norm(), 1e-8) << "frame " << k;
  }
  for (int p = 0; p < n_points; ++p) {
    const double d_true = ((truth[0] * T_B_C0).inverse() * points[p]).z();
    EXPECT_NEAR(1.0 / rho[p], d_true, 1e-6 * d_true) << "point " << p;
  }
}

}  // namespace
}  // namespace linnet
