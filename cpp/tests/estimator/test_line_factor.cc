// Line residual (cam0 / cam1, any frame) and LineManifold: Jacobians against numeric differences through the
// manifolds (the shared checker, which fails on a wrong Jacobian), Ceres' manifold invariants, and the residual's
// geometry against a direct construction.
#include <algorithm>
#include <memory>
#include <random>

#include <ceres/manifold_test_utils.h>
#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/geometry/plucker.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

Pose randomPose(std::mt19937& rng, double spread) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Quat q = expSO3(Vec3(n(rng), n(rng), n(rng)) * 0.5);
  return Pose(q, spread * Vec3(n(rng), n(rng), n(rng)));
}

// A camera looking at a line 3-5 m ahead; returns the line in W and its observed endpoints in camera C.
struct Scene {
  Pose T_W_B, T_B_C;
  Vec6 L_W;
  Vec2 s, e;
};

Scene makeScene(std::mt19937& rng, double noise) {
  std::normal_distribution<double> n(0.0, 1.0);
  Scene sc;
  sc.T_W_B = randomPose(rng, 2.0);
  sc.T_B_C = Pose(expSO3(Vec3(0.1 * n(rng), 0.1 * n(rng), 0.1 * n(rng))), Vec3(0.11 * n(rng), 0.02 * n(rng), 0.01));
  const Pose T_W_C = sc.T_W_B * sc.T_B_C;
  const Vec3 a_C(-0.8 + 0.2 * n(rng), 0.3 * n(rng), 4.0 + 0.5 * n(rng));
  const Vec3 b_C(0.7 + 0.2 * n(rng), 0.3 * n(rng), 3.5 + 0.5 * n(rng));
  sc.L_W = normalisePlucker(pluckerFromPoints(T_W_C * a_C, T_W_C * b_C));
  sc.s = a_C.head<2>() / a_C.z() + noise * Vec2(n(rng), n(rng));
  sc.e = b_C.head<2>() / b_C.z() + noise * Vec2(n(rng), n(rng));
  return sc;
}

TEST(LineFactor, ZeroResidualForTheTrueLineAndDistanceInPixels) {
  std::mt19937 rng(3);
  const Scene sc = makeScene(rng, 0.0);
  LineReprojectionFactor f(sc.s, sc.e, sc.T_B_C, 460.0);
  Vec2 r;
  ASSERT_TRUE(f.evaluate(sc.T_W_B, sc.L_W, &r, nullptr, nullptr));
  EXPECT_LT(r.norm(), 1e-9);
  // Move the observed start point 2 px off the line, perpendicular to it: residual 2 px (sqrt_info = focal).
  const Vec2 d = (sc.e - sc.s).normalized();
  const Vec2 perp(-d.y(), d.x());
  LineReprojectionFactor g(sc.s + perp * (2.0 / 460.0), sc.e, sc.T_B_C, 460.0);
  ASSERT_TRUE(g.evaluate(sc.T_W_B, sc.L_W, &r, nullptr, nullptr));
  EXPECT_NEAR(std::abs(r.x()), 2.0, 1e-6);
  EXPECT_NEAR(r.y(), 0.0, 1e-9);
  // Scale invariance in L.
  Vec2 r2;
  ASSERT_TRUE(g.evaluate(sc.T_W_B, -3.7 * sc.L_W, &r2, nullptr, nullptr));
  EXPECT_LT((r2.cwiseAbs() - r.cwiseAbs()).norm(), 1e-9);
}

TEST(LineFactor, ImageLineMatchesDirectProjection) {
  // l = n_C must be the line through the projections of two points of the 3D line.
  std::mt19937 rng(5);
  for (int trial = 0; trial < 10; ++trial) {
    const Pose T_W_C = randomPose(rng, 3.0);
    const Vec3 a_C(0.5, -0.2, 3.0), b_C(-0.4, 0.6, 5.0);
    const Vec6 L_W = pluckerFromPoints(T_W_C * a_C, T_W_C * b_C);
    const Vec3 l = transformPlucker(T_W_C.inverse(), L_W).head<3>();
    const Vec3 direct = Vec3(a_C / a_C.z()).cross(Vec3(b_C / b_C.z()));
    EXPECT_LT(l.normalized().cross(direct.normalized()).norm(), 1e-9);
    // The transform matrix and the function agree.
    EXPECT_LT((pluckerTransformMatrix(T_W_C.inverse()) * L_W - transformPlucker(T_W_C.inverse(), L_W)).norm(), 1e-12);
  }
}

TEST(LineFactor, ResidualAndLineJacobianMatchThePlainChain) {
  // The factor goes W -> B -> C with the pose's terms computed once per pose. Against the plain chain, the camera's
  // Plücker transform T_C_W = (T_W_B T_B_C)^-1 and r = sqrt_info (s.l, e.l) / |l_12| with d r / d L_W = d r / d l
  // times the transform's top rows: the same to 1e-9 (with the camera's extrinsics, as for cam1).
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const double sqrt_info = 460.0 / 1.5;
  for (int trial = 0; trial < 20; ++trial) {
    const Pose T_W_B = randomPose(rng, 3.0), T_B_C = randomPose(rng, 0.1);
    const Pose T_W_C = T_W_B * T_B_C;
    const Vec6 L_W = pluckerFromPoints(T_W_C * Vec3(0.5 + u(rng), -0.2, 3.0), T_W_C * Vec3(-0.4, 0.6 + u(rng), 5.0));
    const Vec2 s(0.1 + u(rng), -0.05), e(-0.08, 0.12 + u(rng));
    const LineReprojectionFactor f(s, e, T_B_C, sqrt_info);
    Vec2 r;
    Eigen::Matrix<double, 2, 6> J_line;
    ASSERT_TRUE(f.evaluate(T_W_B, L_W, &r, nullptr, &J_line));
    const Eigen::Matrix<double, 6, 6> P = pluckerTransformMatrix(T_W_C.inverse());
    const Vec3 l = (P * L_W).head<3>();
    const double ln = std::hypot(l.x(), l.y());
    const Vec3 sh(s.x(), s.y(), 1.0), eh(e.x(), e.y(), 1.0);
    const Vec2 r_plain = sqrt_info * Vec2(sh.dot(l), eh.dot(l)) / ln;
    Eigen::Matrix<double, 2, 3> A;
    const Vec3 l12(l.x(), l.y(), 0.0);
    A.row(0) = (sh / ln - sh.dot(l) / (ln * ln * ln) * l12).transpose();
    A.row(1) = (eh / ln - eh.dot(l) / (ln * ln * ln) * l12).transpose();
    const Eigen::Matrix<double, 2, 6> J_plain = sqrt_info * A * P.topRows<3>();
    EXPECT_LT((r - r_plain).norm(), 1e-9 * (1.0 + r_plain.norm())) << trial;
    EXPECT_LT((J_line - J_plain).norm(), 1e-9 * (1.0 + J_plain.norm())) << trial;
  }
}

TEST(LineFactor, ReprojectionErrorFromTheInverseCameraPoseIsTheSame) {
  // The outlier checks pass each frame's world -> camera pose, computed once: the same pixels as the plain form.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  for (int trial = 0; trial < 10; ++trial) {
    const Pose T_W_C = randomPose(rng, 3.0);
    const Vec6 L_W = pluckerFromPoints(T_W_C * Vec3(0.5, -0.2, 3.0), T_W_C * Vec3(-0.4, 0.6, 5.0));
    const Vec2 s(0.5 / 3.0 + u(rng) * 0.01, -0.2 / 3.0), e(-0.4 / 5.0, 0.6 / 5.0 + u(rng) * 0.01);
    const double plain = lineReprojectionErrorPx(L_W, T_W_C, s, e, 460.0);
    EXPECT_EQ(lineReprojectionErrorPxFromCw(L_W, T_W_C.inverse(), s, e, 460.0), plain);
    EXPECT_GT(plain, 0.0);
  }
}

TEST(LineFactor, CachedPoseTermsGiveThePlainResultBitForBit) {
  // evaluateTangentSpace keeps the last pose's terms (the line iterations evaluate one factor at one pose many
  // times): every call, whatever came before it (same pose, another pose, only the residual, only the line's
  // Jacobian), must equal a fresh evaluate() exactly.
  std::mt19937 rng(17);
  Scene a = makeScene(rng, 0.004), b = makeScene(rng, 0.004);
  LineReprojectionFactor f(a.s, a.e, a.T_B_C, 460.0 / 1.5);
  double pose_a[7], pose_b[7], line[6];
  setPose(a.T_W_B, pose_a);
  setPose(b.T_W_B, pose_b);
  std::copy(a.L_W.data(), a.L_W.data() + 6, line);
  const auto check = [&](const double* pose, bool want_pose, bool want_line) {
    double r[2], jp[12], jl[12];
    double* jac[2] = {want_pose ? jp : nullptr, want_line ? jl : nullptr};
    const double* params[2] = {pose, line};
    ASSERT_TRUE(f.evaluateTangentSpace(params, r, (want_pose || want_line) ? jac : nullptr));
    Vec2 r0;
    Eigen::Matrix<double, 2, 6> Jp0, Jl0;
    ASSERT_TRUE(f.evaluate(poseFromBlock(pose), Eigen::Map<const Vec6>(line), &r0, &Jp0, &Jl0));
    EXPECT_EQ(r[0], r0.x());
    EXPECT_EQ(r[1], r0.y());
    using RowMajor26 = Eigen::Matrix<double, 2, 6, Eigen::RowMajor>;
    if (want_pose) {
      EXPECT_EQ(Eigen::Map<RowMajor26>(jp), Jp0);
    }
    if (want_line) {
      EXPECT_EQ(Eigen::Map<RowMajor26>(jl), Jl0);
    }
  };
  check(pose_a, false, false);  // residual only: no K yet
  check(pose_a, false, true);   // the line's Jacobian at the same pose: K added
  check(pose_a, false, true);   // from the cache
  line[0] += 1e-3;              // the line moves, the pose does not
  check(pose_a, false, true);
  check(pose_b, true, true);    // another pose
  check(pose_a, true, false);
  check(pose_a, false, true);
}

TEST(LineFactor, SharedPoseTermsGiveThePlainResultBitForBit) {
  // Factors of one frame camera share its pose terms: whichever factor computed them, at whichever pose before,
  // each factor's evaluation equals a fresh evaluate() of its own exactly.
  std::mt19937 rng(19);
  const Scene a = makeScene(rng, 0.004), b = makeScene(rng, 0.004), c = makeScene(rng, 0.004);
  const auto shared = std::make_shared<SharedLinePoseTerms>(a.T_B_C);
  // Three lines seen by the same camera (a's extrinsics), one of them also with a factor of its own.
  const LineReprojectionFactor f1(a.s, a.e, a.T_B_C, 460.0, shared), f2(b.s, b.e, a.T_B_C, 300.0, shared),
      f3(c.s, c.e, a.T_B_C, 460.0, shared), own(b.s, b.e, a.T_B_C, 300.0);
  double pose_a[7], pose_b[7], line_a[6], line_b[6];
  setPose(a.T_W_B, pose_a);
  setPose(b.T_W_B, pose_b);
  std::copy(a.L_W.data(), a.L_W.data() + 6, line_a);
  std::copy(b.L_W.data(), b.L_W.data() + 6, line_b);
  using RowMajor26 = Eigen::Matrix<double, 2, 6, Eigen::RowMajor>;
  const auto check = [&](const LineReprojectionFactor& f, const double* pose, const double* line) {
    double r[2], jp[12], jl[12];
    double* jac[2] = {jp, jl};
    const double* params[2] = {pose, line};
    ASSERT_TRUE(f.evaluateTangentSpace(params, r, jac));
    Vec2 r0;
    Eigen::Matrix<double, 2, 6> Jp0, Jl0;
    ASSERT_TRUE(f.evaluate(poseFromBlock(pose), Eigen::Map<const Vec6>(line), &r0, &Jp0, &Jl0));
    EXPECT_EQ(r[0], r0.x());
    EXPECT_EQ(r[1], r0.y());
    EXPECT_EQ(Eigen::Map<RowMajor26>(jp), Jp0);
    EXPECT_EQ(Eigen::Map<RowMajor26>(jl), Jl0);
  };
  check(f1, pose_a, line_a);  // computes the shared terms
  check(f2, pose_a, line_b);  // uses them
  check(f3, pose_b, line_a);  // another pose: computes them anew
  check(f1, pose_b, line_b);
  check(f2, pose_a, line_a);  // and back
  check(own, pose_a, line_b);
  // The same factor with and without shared terms: the same numbers.
  double r_s[2], r_o[2], jp_s[12], jp_o[12];
  double* jac_s[2] = {jp_s, nullptr};
  double* jac_o[2] = {jp_o, nullptr};
  const double* params[2] = {pose_b, line_b};
  ASSERT_TRUE(f2.evaluateTangentSpace(params, r_s, jac_s));
  ASSERT_TRUE(own.evaluateTangentSpace(params, r_o, jac_o));
  EXPECT_EQ(r_s[0], r_o[0]);
  EXPECT_EQ(r_s[1], r_o[1]);
  EXPECT_EQ(Eigen::Map<RowMajor26>(jp_s), Eigen::Map<RowMajor26>(jp_o));
  // Terms of other extrinsics are refused, at construction and at reset.
  EXPECT_THROW(LineReprojectionFactor(a.s, a.e, b.T_B_C, 460.0, shared), UsageError);
  LineReprojectionFactor g(a.s, a.e, b.T_B_C, 460.0);
  EXPECT_THROW(g.reset(a.s, a.e, b.T_B_C, 460.0, shared), UsageError);
}

TEST(LineFactor, JacobiansMatchNumericCam0AndCam1) {
  std::mt19937 rng(11);
  const PoseManifold pose_manifold;
  const LineManifold line_manifold;
  for (int trial = 0; trial < 20; ++trial) {
    // Noisy observations: non-zero residuals exercise every term. Trials alternate a cam0-like (near identity)
    // and a cam1-like (offset baseline) extrinsic; the pose is any window frame (host or not: the factor has none).
    Scene sc = makeScene(rng, 0.004);
    if (trial % 2 == 1) sc.T_B_C = Pose(sc.T_B_C.q, sc.T_B_C.p + Vec3(0.11, 0.0, 0.0));
    LineReprojectionFactor f(sc.s, sc.e, sc.T_B_C, 460.0 / 1.5);
    double pose[7], line[6];
    setPose(sc.T_W_B, pose);
    std::copy(sc.L_W.data(), sc.L_W.data() + 6, line);
    EXPECT_TRUE(testing::jacobiansMatch(f, {pose, line}, {&pose_manifold, &line_manifold}, 1e-5)) << trial;
  }
}

TEST(LineFactor, CheckerRejectsAWrongJacobian) {
  // A factor whose line Jacobian is off by a sign in one column must fail the same check.
  class Broken : public ceres::SizedCostFunction<2, 7, 6> {
   public:
    explicit Broken(const LineReprojectionFactor& f) : f_(f) {}
    bool Evaluate(double const* const* p, double* r, double** J) const override {
      if (!f_.Evaluate(p, r, J)) return false;
      if (J != nullptr && J[1] != nullptr) {
        J[1][2] = -J[1][2];
        J[1][8] = -J[1][8];
      }
      return true;
    }

   private:
    const LineReprojectionFactor& f_;
  };
  std::mt19937 rng(13);
  const Scene sc = makeScene(rng, 0.004);
  LineReprojectionFactor f(sc.s, sc.e, sc.T_B_C, 300.0);
  Broken broken(f);
  const PoseManifold pose_manifold;
  const LineManifold line_manifold;
  double pose[7], line[6];
  setPose(sc.T_W_B, pose);
  std::copy(sc.L_W.data(), sc.L_W.data() + 6, line);
  EXPECT_FALSE(testing::checkJacobians(broken, {pose, line}, {&pose_manifold, &line_manifold}).ok(1e-5));
}

TEST(LineManifold, CeresInvariantsHoldAtRandomLines) {
  using namespace ceres;  // NOLINT: the invariant macro names ceres' matchers unqualified
  std::mt19937 rng(17);
  std::normal_distribution<double> n(0.0, 1.0);
  const LineManifold manifold;
  for (int trial = 0; trial < 20; ++trial) {
    // Lines 0.5-5 m from the origin (phi well inside (0, pi/2)), small steps (the representation's chart).
    const Vec3 p(n(rng), n(rng), n(rng));
    const Vec3 d(n(rng), n(rng), n(rng));
    const Vec3 a = p.normalized() * (0.5 + 4.5 * std::abs(n(rng)) / 3.0);
    ceres::Vector x = normalisePlucker(pluckerFromPoints(a, a + d));
    ceres::Vector delta(4), step(4);
    for (int i = 0; i < 4; ++i) {
      delta[i] = 0.05 * n(rng);
      step[i] = 0.05 * n(rng);
    }
    ceres::Vector y(6);
    ASSERT_TRUE(manifold.Plus(x.data(), step.data(), y.data()));
    EXPECT_THAT_MANIFOLD_INVARIANTS_HOLD(manifold, x, delta, y, 1e-9);
  }
}

TEST(LineManifold, PlusIsTheOrthonormalUpdate) {
  const Vec6 L = normalisePlucker(pluckerFromPoints(Vec3(1, 2, 3), Vec3(2, 2, 5)));
  OrthonormalLine o = toOrthonormal(L);
  EXPECT_LT((fromOrthonormal(o) - L).norm(), 1e-12);
  EXPECT_LT((o.U.transpose() * o.U - Mat3::Identity()).norm(), 1e-12);
  EXPECT_NEAR(o.U.determinant(), 1.0, 1e-12);
  // Distance to the origin = w1 / w2.
  EXPECT_NEAR(o.w.x() / o.w.y(), pluckerDistanceToOrigin(L), 1e-12);
  const double delta[4] = {0.01, -0.02, 0.03, 0.04};
  double out[6];
  LineManifold().Plus(L.data(), delta, out);
  const Mat3 U2 = o.U * expSO3(Vec3(0.01, -0.02, 0.03)).toRotationMatrix();
  const double phi = std::atan2(o.w.y(), o.w.x()) + 0.04;
  Vec6 expected;
  expected << std::cos(phi) * U2.col(0), std::sin(phi) * U2.col(1);
  EXPECT_LT((Eigen::Map<const Vec6>(out) - expected).norm(), 1e-12);
  // Klein constraint holds after the update.
  EXPECT_NEAR(Eigen::Map<const Vec3>(out).dot(Eigen::Map<const Vec3>(out + 3)), 0.0, 1e-14);
}

}  // namespace
}  // namespace linnet
