// Online rig extrinsics, cam1's stereo correction and time offset (RigCorrectedFactor, its stereoCorrected form,
// PointStereoCorrectedFactor, TimeShiftedFactor): the wrapped point and line residuals equal the inner factors at the
// corrected / shifted poses, and their Jacobians (body poses, landmark, corrections, offset; alone and nested as the
// estimator nests them) match numeric differences through the manifolds (the shared checker, which fails on a wrong
// Jacobian).
#include "linnet/estimator/factors/pose_wrappers.h"

#include <array>
#include <memory>
#include <random>

#include <ceres/sized_cost_function.h>
#include <gtest/gtest.h>

#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/factors/point_factors.h"
#include "linnet/estimator/factors/zero_velocity_factor.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/geometry/plucker.h"
#include "support/jacobian_check.h"

namespace linnet {
namespace {

constexpr double kFocal = 458.0;
constexpr double kTol = 1e-6;

Pose randomPose(std::mt19937& rng, double angle, double spread) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose(expSO3(angle * Vec3(n(rng), n(rng), n(rng))), spread * Vec3(n(rng), n(rng), n(rng)));
}

// EuRoC-like extrinsics: camera looking along the body's x axis, 11 cm baseline.
Pose cam0() { return Pose(Mat3((Mat3() << 0, 0, 1, -1, 0, 0, 0, -1, 0).finished()), Vec3(-0.02, -0.06, 0.01)); }
Pose cam1() { return cam0() * Pose(expSO3(Vec3(0.002, -0.001, 0.003)), Vec3(0.11, 0.0, 0.0)); }

std::array<double, 7> block(const Pose& T) {
  std::array<double, 7> b{};
  setPose(T, b.data());
  return b;
}

struct PointCase {
  Pose T_W_Bi, T_W_Bj, T_B_R0, T_B_R;
  Vec2 uv_host, uv_target;
  double rho = 0.3;
};

/// Two body poses seeing a point 1-10 m ahead of the host camera; the corrections are ~0.5 deg / 1 cm.
PointCase pointCase(std::mt19937& rng, const Pose& T_B_Ct) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(1.0, 10.0);
  PointCase c;
  for (;;) {
    c.T_W_Bi = randomPose(rng, 1.0, 3.0);
    c.T_W_Bj = c.T_W_Bi * randomPose(rng, 0.1, 0.2);
    c.T_B_R0 = randomPose(rng, 0.01, 0.01);
    c.T_B_R = randomPose(rng, 0.01, 0.01);
    c.uv_host = Vec2(0.4 * u(rng), 0.3 * u(rng));
    const double d = depth(rng);
    c.rho = 1.0 / d;
    const Vec3 p_W = (c.T_W_Bi * c.T_B_R * cam0()) * (Vec3(c.uv_host.x(), c.uv_host.y(), 1.0) * d);
    const Vec3 p_C = (c.T_W_Bj * c.T_B_R * T_B_Ct).inverse() * p_W;
    if (p_C.z() < 0.5) continue;
    c.uv_target = p_C.head<2>() / p_C.z() + Vec2(u(rng), u(rng)) * (2.0 / kFocal);  // off the truth
    return c;
  }
}

/// `wrapped` at `pw` and `direct` at `pd` give the same 2-D residual.
void expectSameResidual(const ceres::CostFunction& wrapped, const double* const* pw, const ceres::CostFunction& direct,
                        const double* const* pd) {
  double rw[2], rd[2];
  ASSERT_TRUE(wrapped.Evaluate(pw, rw, nullptr));
  ASSERT_TRUE(direct.Evaluate(pd, rd, nullptr));
  EXPECT_NEAR(rw[0], rd[0], 1e-9);
  EXPECT_NEAR(rw[1], rd[1], 1e-9);
}

struct LineCase {
  Vec6 L;     // the line in W
  Vec2 s, e;  // its endpoints seen by the camera, about a pixel off
};

/// A line about 4 m ahead of the camera at T_W_C, and its observed segment in that camera.
LineCase lineCase(std::mt19937& rng, const Pose& T_W_C) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Vec3 a_C(-0.8 + 0.2 * n(rng), 0.3 * n(rng), 4.0 + 0.5 * n(rng));
  const Vec3 b_C(0.7 + 0.2 * n(rng), 0.3 * n(rng), 3.5 + 0.5 * n(rng));
  LineCase c;
  c.L = normalisePlucker(pluckerFromPoints(T_W_C * a_C, T_W_C * b_C));
  c.s = a_C.head<2>() / a_C.z() + Vec2(n(rng), n(rng)) / kFocal;
  c.e = b_C.head<2>() / b_C.z() + Vec2(n(rng), n(rng)) / kFocal;
  return c;
}

TEST(RigFactor, PointResidualEqualsTheInnerFactorWithCorrectedExtrinsics) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const PointCase c = pointCase(rng, cam1());
    const double s = pointSqrtInformation(kFocal);
    // Built with the extrinsics of correction R0, evaluated at correction R: as if built with R.
    auto inner = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, c.T_B_R0 * cam0(),
                                                           c.T_B_R0 * cam1(), s);
    const PointReprojectionFactor direct(c.uv_host, c.uv_target, c.T_B_R * cam0(), c.T_B_R * cam1(), s);
    const RigCorrectedFactor wrapped(inner, std::vector<int>{0, 1}, c.T_B_R0);
    auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), br = block(c.T_B_R);
    double rho = c.rho;
    const double* pw[4] = {bi.data(), bj.data(), &rho, br.data()};
    const double* pd[3] = {bi.data(), bj.data(), &rho};
    expectSameResidual(wrapped, pw, direct, pd);
    EXPECT_EQ(wrapped.parameter_block_sizes(), (std::vector<int32_t>{7, 7, 1, 7}));
  }
}

TEST(RigFactor, PointJacobiansSameCameraAndLeftToRight) {
  std::mt19937 rng(12);
  const PoseManifold pm;
  for (int trial = 0; trial < 60; ++trial) {
    const Pose target = trial % 2 == 0 ? cam0() : cam1();
    const PointCase c = pointCase(rng, target);
    auto inner = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, c.T_B_R0 * cam0(),
                                                           c.T_B_R0 * target, pointSqrtInformation(kFocal));
    const RigCorrectedFactor f(inner, std::vector<int>{0, 1}, c.T_B_R0);
    auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), br = block(c.T_B_R);
    double rho = c.rho;
    ASSERT_TRUE(testing::jacobiansMatch(f, {bi.data(), bj.data(), &rho, br.data()}, {&pm, &pm, nullptr, &pm}, kTol))
        << "trial " << trial;
  }
}

TEST(RigFactor, LineJacobiansAndResidual) {
  std::mt19937 rng(13);
  const PoseManifold pm;
  const LineManifold lm;
  for (int trial = 0; trial < 60; ++trial) {
    const Pose T_W_B = randomPose(rng, 1.0, 3.0);
    const Pose T_B_R0 = randomPose(rng, 0.01, 0.01), T_B_R = randomPose(rng, 0.01, 0.01);
    const Pose T_B_C = trial % 2 == 0 ? cam0() : cam1();
    const Pose T_W_C = T_W_B * T_B_R * T_B_C;
    LineCase c = lineCase(rng, T_W_C);
    Vec6& L = c.L;
    auto inner = std::make_shared<LineReprojectionFactor>(c.s, c.e, T_B_R0 * T_B_C, kFocal);
    const LineReprojectionFactor direct(c.s, c.e, T_B_R * T_B_C, kFocal);
    const RigCorrectedFactor f(inner, std::vector<int>{0}, T_B_R0);
    auto bp = block(T_W_B), br = block(T_B_R);
    const double* pw[3] = {bp.data(), L.data(), br.data()};
    const double* pd[2] = {bp.data(), L.data()};
    expectSameResidual(f, pw, direct, pd);
    ASSERT_TRUE(testing::jacobiansMatch(f, {bp.data(), L.data(), br.data()}, {&pm, &lm, &pm}, kTol))
        << "trial " << trial;
  }
}

/// The wrapped factor with one entry of its correction Jacobian scaled: the checker must reject it.
class CorruptRig : public ceres::CostFunction {
 public:
  CorruptRig(const RigCorrectedFactor& f, int entry) : f_(f), entry_(entry) {
    set_num_residuals(f.num_residuals());
    *mutable_parameter_block_sizes() = f.parameter_block_sizes();
  }
  bool Evaluate(double const* const* p, double* r, double** J) const override {
    if (!f_.Evaluate(p, r, J)) return false;
    if (J != nullptr && J[3] != nullptr) J[3][entry_] *= 1.0 + 1e-3;
    return true;
  }

 private:
  const RigCorrectedFactor& f_;
  int entry_;
};

TEST(RigFactor, CheckerRejectsAWrongCorrectionJacobian) {
  std::mt19937 rng(14);
  const PoseManifold pm;
  const PointCase c = pointCase(rng, cam1());
  auto inner = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, c.T_B_R0 * cam0(),
                                                         c.T_B_R0 * cam1(), pointSqrtInformation(kFocal));
  const RigCorrectedFactor f(inner, std::vector<int>{0, 1}, c.T_B_R0);
  auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), br = block(c.T_B_R);
  double rho = c.rho;
  const std::vector<double*> params = {bi.data(), bj.data(), &rho, br.data()};
  ASSERT_TRUE(testing::checkJacobians(f, params, {&pm, &pm, nullptr, &pm}).ok(kTol));
  for (int entry : {1, 4, 7 + 2, 7 + 5}) {  // position and rotation columns of both rows
    const CorruptRig bad(f, entry);
    EXPECT_FALSE(testing::checkJacobians(bad, params, {&pm, &pm, nullptr, &pm}).ok(kTol)) << "entry " << entry;
  }
}

TEST(TimeShiftedFactor, ResidualIsTheInnerFactorAtTheShiftedPoses) {
  std::mt19937 rng(15);
  for (int trial = 0; trial < 20; ++trial) {
    const PointCase c = pointCase(rng, cam1());
    const double s = pointSqrtInformation(kFocal);
    auto inner = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, cam0(), cam1(), s);
    const std::vector<Vec3> v = {Vec3(1.0, -0.5, 0.2), Vec3(0.3, 0.8, -0.1)};
    const std::vector<Vec3> w = {Vec3(0.5, -1.0, 0.3), Vec3(-0.2, 0.4, 1.5)};
    const TimeShiftedFactor f(inner, std::vector<int>{0, 1}, v, w);
    double td = 0.004;
    // By hand: the body at t - t_d to first order.
    const Pose Ti(c.T_W_Bi.q * expSO3(-td * w[0]), c.T_W_Bi.p - td * v[0]);
    const Pose Tj(c.T_W_Bj.q * expSO3(-td * w[1]), c.T_W_Bj.p - td * v[1]);
    auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), si = block(Ti), sj = block(Tj);
    double rho = c.rho;
    const double* pw[4] = {bi.data(), bj.data(), &rho, &td};
    const double* pd[3] = {si.data(), sj.data(), &rho};
    expectSameResidual(f, pw, *inner, pd);
    EXPECT_EQ(f.parameter_block_sizes(), (std::vector<int32_t>{7, 7, 1, 1}));
  }
}

// A two-frame point residual with random rates and offset, as the time-shift tests use it.
struct TimedPoint {
  PointCase c;
  std::vector<Vec3> v, w;
  double td = 0.0, rho = 0.0;
  std::array<double, 7> bi{}, bj{}, br{};
  std::shared_ptr<PointReprojectionFactor> point;
};

TimedPoint timedPoint(std::mt19937& rng, int trial) {
  std::normal_distribution<double> n(0.0, 1.0);
  auto rnd = [&](double scale) { return Vec3(scale * n(rng), scale * n(rng), scale * n(rng)); };
  TimedPoint t;
  t.c = pointCase(rng, trial % 2 == 0 ? cam0() : cam1());
  t.v = {rnd(1.0), rnd(1.0)};
  t.w = {rnd(1.0), rnd(1.0)};
  t.td = 0.01 * n(rng);
  t.rho = t.c.rho;
  t.bi = block(t.c.T_W_Bi);
  t.bj = block(t.c.T_W_Bj);
  t.br = block(t.c.T_B_R);
  t.point = std::make_shared<PointReprojectionFactor>(t.c.uv_host, t.c.uv_target, t.c.T_B_R0 * cam0(),
                                                      t.c.T_B_R0 * (trial % 2 == 0 ? cam0() : cam1()),
                                                      pointSqrtInformation(kFocal));
  return t;
}

TEST(TimeShiftedFactor, JacobiansAloneAndAroundTheRigCorrection) {
  std::mt19937 rng(16);
  const PoseManifold pm;
  const LineManifold lm;
  for (int trial = 0; trial < 40; ++trial) {
    TimedPoint t = timedPoint(rng, trial);
    auto& [c, v, w, td, rho, bi, bj, br, point] = t;
    const TimeShiftedFactor alone(point, std::vector<int>{0, 1}, v, w);
    ASSERT_TRUE(testing::jacobiansMatch(alone, {bi.data(), bj.data(), &rho, &td}, {&pm, &pm, nullptr, nullptr}, kTol))
        << "trial " << trial;
    // As the estimator nests them: the rig correction inside, the time shift outside.
    auto rig = std::make_shared<RigCorrectedFactor>(point, std::vector<int>{0, 1}, c.T_B_R0);
    const TimeShiftedFactor nested(rig, std::vector<int>{0, 1}, v, w);
    ASSERT_TRUE(testing::jacobiansMatch(nested, {bi.data(), bj.data(), &rho, br.data(), &td},
                                        {&pm, &pm, nullptr, &pm, nullptr}, kTol))
        << "trial " << trial;
    // A line residual.
    const Pose T_W_C = c.T_W_Bi * cam0();
    Vec6 L = normalisePlucker(pluckerFromPoints(T_W_C * Vec3(-0.8, 0.1, 4.0), T_W_C * Vec3(0.7, -0.2, 3.5)));
    auto line = std::make_shared<LineReprojectionFactor>(Vec2(-0.2, 0.03), Vec2(0.2, -0.05), cam0(), kFocal);
    const TimeShiftedFactor shifted_line(line, std::vector<int>{0}, std::vector<Vec3>{v[0]}, std::vector<Vec3>{w[0]});
    ASSERT_TRUE(testing::jacobiansMatch(shifted_line, {bi.data(), L.data(), &td}, {&pm, &lm, nullptr}, kTol))
        << "trial " << trial;
  }
}

// The fused rig-and-time wrapper the estimator uses while both are estimated: the same residual and Jacobians as the
// nested pair (to rounding: the maps are composed before the chain rule), its Jacobians right by the shared checker,
// for a two-pose point residual and a one-pose line residual, with a shared memo and without.
TEST(RigTimeShiftedFactor, EqualsTheNestedWrappersAndItsJacobiansMatch) {
  std::mt19937 rng(31);
  const PoseManifold pm;
  const LineManifold lm;
  const auto memo = std::make_shared<PoseTransformMemo>();
  for (int trial = 0; trial < 20; ++trial) {
    TimedPoint t = timedPoint(rng, trial);
    auto& [c, v, w, td, rho, bi, bj, br, point] = t;
    auto rig = std::make_shared<RigCorrectedFactor>(point, std::vector<int>{0, 1}, c.T_B_R0);
    const TimeShiftedFactor nested(rig, std::vector<int>{0, 1}, v, w);
    RigTimeShiftedFactor fused(point, std::vector<int>{0, 1}, c.T_B_R0, v, w);
    if (trial % 4 >= 2) fused.useMemo(memo, {100 + trial, 200 + trial});
    EXPECT_EQ(fused.parameter_block_sizes(), nested.parameter_block_sizes());
    const double* params[] = {bi.data(), bj.data(), &rho, br.data(), &td};
    for (int pass = 0; pass < 2; ++pass) {  // the second pass answers from the memo where one is used
      std::array<double, 2> ra{}, rb{};
      std::array<std::array<double, 14>, 5> ja{}, jb{};
      double* jac_a[] = {ja[0].data(), ja[1].data(), ja[2].data(), ja[3].data(), ja[4].data()};
      double* jac_b[] = {jb[0].data(), jb[1].data(), jb[2].data(), jb[3].data(), jb[4].data()};
      ASSERT_TRUE(nested.Evaluate(params, ra.data(), jac_a));
      ASSERT_TRUE(fused.Evaluate(params, rb.data(), jac_b));
      for (int i = 0; i < 2; ++i) EXPECT_NEAR(ra[i], rb[i], 1e-12 * (1.0 + std::abs(ra[i]))) << "trial " << trial;
      for (std::size_t b = 0; b < 5; ++b)
        for (std::size_t i = 0; i < 14; ++i)
          EXPECT_NEAR(ja[b][i], jb[b][i], 1e-9 * (1.0 + std::abs(ja[b][i]))) << "trial " << trial << " block " << b;
    }
    ASSERT_TRUE(testing::jacobiansMatch(fused, {bi.data(), bj.data(), &rho, br.data(), &td},
                                        {&pm, &pm, nullptr, &pm, nullptr}, kTol))
        << "trial " << trial;
    // A line residual (one pose block).
    const Pose T_W_C = c.T_W_Bi * c.T_B_R * cam0();
    Vec6 L = normalisePlucker(pluckerFromPoints(T_W_C * Vec3(-0.8, 0.1, 4.0), T_W_C * Vec3(0.7, -0.2, 3.5)));
    auto line = std::make_shared<LineReprojectionFactor>(Vec2(-0.2, 0.03), Vec2(0.2, -0.05), c.T_B_R0 * cam0(), kFocal);
    const RigTimeShiftedFactor fused_line(line, std::vector<int>{0}, c.T_B_R0, std::vector<Vec3>{v[0]},
                                          std::vector<Vec3>{w[0]});
    ASSERT_TRUE(testing::jacobiansMatch(fused_line, {bi.data(), L.data(), br.data(), &td}, {&pm, &lm, &pm, nullptr},
                                        kTol))
        << "trial " << trial;
  }
}

TEST(PoseTransformMemo, SharedTransformsGiveTheSameResidualsAndJacobiansBitForBit) {
  // Two residuals of the same two frames (time shift outside, rig inside, as the estimator nests them), one pair
  // with memos shared as the estimator shares them and one without; evaluated at changing values (a memo must never
  // answer for other inputs), with and without Jacobians in either order.
  std::mt19937 rng(23);
  std::normal_distribution<double> n(0.0, 1.0);
  auto rnd = [&](double scale) { return Vec3(scale * n(rng), scale * n(rng), scale * n(rng)); };
  const PointCase c = pointCase(rng, cam0());
  const std::vector<Vec3> v = {rnd(1.0), rnd(1.0)}, w = {rnd(1.0), rnd(1.0)};
  const auto rig_memo = std::make_shared<PoseTransformMemo>();
  const auto time_memo = std::make_shared<PoseTransformMemo>();
  std::vector<std::shared_ptr<TimeShiftedFactor>> plain, memoised;
  for (int r = 0; r < 2; ++r) {
    auto point = std::make_shared<PointReprojectionFactor>(c.uv_host + Vec2(0.01 * r, 0.0), c.uv_target,
                                                           c.T_B_R0 * cam0(), c.T_B_R0 * cam0(),
                                                           pointSqrtInformation(kFocal));
    for (const bool memo : {false, true}) {
      auto rig = std::make_shared<RigCorrectedFactor>(point, std::vector<int>{0, 1}, c.T_B_R0);
      auto shifted = std::make_shared<TimeShiftedFactor>(rig, std::vector<int>{0, 1}, v, w);
      if (memo) {
        rig->useMemo(rig_memo, {0, 0});
        shifted->useMemo(time_memo, {10, 11});  // the frames of blocks 0 and 1
      }
      (memo ? memoised : plain).push_back(shifted);
    }
  }
  auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), br = block(c.T_B_R);
  double rho = c.rho, td = 0.003;
  for (int step = 0; step < 6; ++step) {
    if (step == 2) bi = block(c.T_W_Bi * randomPose(rng, 0.01, 0.01));
    if (step == 3) br = block(c.T_B_R * randomPose(rng, 0.001, 0.001));
    if (step == 4) td = 0.004;
    const double* params[] = {bi.data(), bj.data(), &rho, br.data(), &td};
    for (const bool with_jacobians : {step % 2 == 0, step % 2 != 0}) {
      for (std::size_t r = 0; r < 2; ++r) {
        std::array<double, 2> res_a{}, res_b{};
        std::array<std::array<double, 14>, 5> ja{}, jb{};
        double* jac_a[] = {ja[0].data(), ja[1].data(), ja[2].data(), ja[3].data(), ja[4].data()};
        double* jac_b[] = {jb[0].data(), jb[1].data(), jb[2].data(), jb[3].data(), jb[4].data()};
        ASSERT_TRUE(plain[r]->Evaluate(params, res_a.data(), with_jacobians ? jac_a : nullptr));
        ASSERT_TRUE(memoised[r]->Evaluate(params, res_b.data(), with_jacobians ? jac_b : nullptr));
        EXPECT_EQ(res_a, res_b) << "step " << step << " residual " << r;
        EXPECT_EQ(ja, jb) << "step " << step << " residual " << r;
      }
    }
  }
}

TEST(PoseWrappedFactor, LandmarkJacobianAloneEqualsItsPartOfTheFullRequestBitForBit) {
  // The solver's landmark iterations ask for the landmark's Jacobian alone; the wrappers then skip their transforms'
  // derivatives. Time shift outside, rig inside, as the estimator nests them, with memos shared.
  std::mt19937 rng(29);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 10; ++trial) {
    const Pose T_W_B = randomPose(rng, 1.0, 3.0);
    const Pose T_B_R0 = randomPose(rng, 0.01, 0.01), T_B_R = randomPose(rng, 0.01, 0.01);
    LineCase c = lineCase(rng, T_W_B * T_B_R * cam0());
    auto line = std::make_shared<LineReprojectionFactor>(c.s, c.e, T_B_R0 * cam0(), kFocal);
    auto rig = std::make_shared<RigCorrectedFactor>(line, std::vector<int>{0}, T_B_R0);
    const auto rig_memo = std::make_shared<PoseTransformMemo>();
    rig->useMemo(rig_memo, {0});
    const TimeShiftedFactor f(rig, std::vector<int>{0}, std::vector<Vec3>{Vec3(n(rng), n(rng), n(rng))},
                              std::vector<Vec3>{Vec3(n(rng), n(rng), n(rng))});
    auto bp = block(T_W_B), br = block(T_B_R);
    double td = 0.005 * n(rng);
    const double* params[] = {bp.data(), c.L.data(), br.data(), &td};
    std::array<double, 2> r_all{}, r_one{};
    std::array<std::array<double, 14>, 4> all{}, one{};
    double* j_all[] = {all[0].data(), all[1].data(), all[2].data(), all[3].data()};
    double* j_one[] = {nullptr, one[1].data(), nullptr, nullptr};
    ASSERT_TRUE(f.Evaluate(params, r_one.data(), j_one));  // first: the memo holds no derivatives yet
    ASSERT_TRUE(f.Evaluate(params, r_all.data(), j_all));
    EXPECT_EQ(r_all, r_one) << "trial " << trial;
    EXPECT_EQ(all[1], one[1]) << "trial " << trial;
    EXPECT_NE(all[0], one[0]);  // the pose's Jacobian was written in the full request only
  }
}

// --- cam1's stereo correction S (cam1 at T_B_C1 * S)

TEST(StereoCorrection, Cam1PointResidualIsTheInnerFactorWithCam1Corrected) {
  std::mt19937 rng(17);
  const PoseManifold pm;
  for (int trial = 0; trial < 40; ++trial) {
    const PointCase c = pointCase(rng, cam1());
    const Pose S0 = randomPose(rng, 0.005, 0.001), S = randomPose(rng, 0.005, 0.001);
    const double s = pointSqrtInformation(kFocal);
    // Built with the rig correction R0 and cam1's S0 in its extrinsics, evaluated at S.
    const Pose T_B_Ct = c.T_B_R0 * cam1() * S0;
    auto inner = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, c.T_B_R0 * cam0(), T_B_Ct, s);
    const PointReprojectionFactor direct(c.uv_host, c.uv_target, c.T_B_R0 * cam0(), c.T_B_R0 * cam1() * S, s);
    const auto wrapped = RigCorrectedFactor::stereoCorrected(inner, 1, T_B_Ct, S0);
    auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), bs = block(S), br = block(c.T_B_R);
    double rho = c.rho;
    const double* pw[4] = {bi.data(), bj.data(), &rho, bs.data()};
    const double* pd[3] = {bi.data(), bj.data(), &rho};
    expectSameResidual(*wrapped, pw, direct, pd);
    ASSERT_TRUE(testing::jacobiansMatch(*wrapped, {bi.data(), bj.data(), &rho, bs.data()}, {&pm, &pm, nullptr, &pm},
                                        kTol))
        << "trial " << trial;
    // Nested as the estimator nests them: S innermost, then the rig correction, then the time shift.
    auto rig = std::make_shared<RigCorrectedFactor>(wrapped, std::vector<int>{0, 1}, c.T_B_R0);
    const std::vector<Vec3> v = {Vec3(1.0, -0.5, 0.2), Vec3(0.3, 0.8, -0.1)};
    const std::vector<Vec3> w = {Vec3(0.5, -1.0, 0.3), Vec3(-0.2, 0.4, 1.5)};
    const TimeShiftedFactor nested(rig, std::vector<int>{0, 1}, v, w);
    double td = 0.003;
    ASSERT_TRUE(testing::jacobiansMatch(nested, {bi.data(), bj.data(), &rho, bs.data(), br.data(), &td},
                                        {&pm, &pm, nullptr, &pm, &pm, nullptr}, kTol))
        << "trial " << trial;
    // The rig and S together give the camera T_W_Bj * T_B_R * T_B_C1 * S.
    const PointReprojectionFactor both(c.uv_host, c.uv_target, c.T_B_R * cam0(), c.T_B_R * cam1() * S, s);
    const double* pr[5] = {bi.data(), bj.data(), &rho, bs.data(), br.data()};
    expectSameResidual(*rig, pr, both, pd);
  }
}

TEST(StereoCorrection, Cam1LineResidualAndJacobians) {
  std::mt19937 rng(18);
  const PoseManifold pm;
  const LineManifold lm;
  for (int trial = 0; trial < 40; ++trial) {
    const Pose T_W_B = randomPose(rng, 1.0, 3.0);
    const Pose S0 = randomPose(rng, 0.005, 0.001), S = randomPose(rng, 0.005, 0.001);
    const Pose T_W_C = T_W_B * cam1() * S;
    LineCase c = lineCase(rng, T_W_C);
    Vec6& L = c.L;
    auto inner = std::make_shared<LineReprojectionFactor>(c.s, c.e, cam1() * S0, kFocal);
    const LineReprojectionFactor direct(c.s, c.e, cam1() * S, kFocal);
    const auto f = RigCorrectedFactor::stereoCorrected(inner, 0, cam1() * S0, S0);
    auto bp = block(T_W_B), bs = block(S);
    const double* pw[3] = {bp.data(), L.data(), bs.data()};
    const double* pd[2] = {bp.data(), L.data()};
    expectSameResidual(*f, pw, direct, pd);
    ASSERT_TRUE(testing::jacobiansMatch(*f, {bp.data(), L.data(), bs.data()}, {&pm, &lm, &pm}, kTol))
        << "trial " << trial;
  }
}

TEST(StereoCorrection, GeneralFormJacobians) {
  // T_W_B * L * X * Rr with arbitrary constants (the form both corrections use).
  std::mt19937 rng(19);
  const PoseManifold pm;
  for (int trial = 0; trial < 40; ++trial) {
    const PointCase c = pointCase(rng, cam1());
    auto inner = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, cam0(), cam1(),
                                                           pointSqrtInformation(kFocal));
    const RigCorrectedFactor f(inner, std::vector<int>{0, 1}, randomPose(rng, 0.3, 0.1), randomPose(rng, 0.3, 0.1));
    auto bi = block(c.T_W_Bi), bj = block(c.T_W_Bj), bx = block(randomPose(rng, 0.01, 0.01));
    double rho = c.rho;
    ASSERT_TRUE(testing::jacobiansMatch(f, {bi.data(), bj.data(), &rho, bx.data()}, {&pm, &pm, nullptr, &pm}, kTol))
        << "trial " << trial;
  }
}

/// A factor with one entry of one block's Jacobian scaled: the checker must reject it.
class CorruptEntry : public ceres::CostFunction {
 public:
  CorruptEntry(const ceres::CostFunction& f, int block, int entry) : f_(f), block_(block), entry_(entry) {
    set_num_residuals(f.num_residuals());
    *mutable_parameter_block_sizes() = f.parameter_block_sizes();
  }
  bool Evaluate(double const* const* p, double* r, double** J) const override {
    if (!f_.Evaluate(p, r, J)) return false;
    if (J != nullptr && J[block_] != nullptr) J[block_][entry_] *= 1.0 + 1e-3;
    return true;
  }

 private:
  const ceres::CostFunction& f_;
  int block_, entry_;
};

TEST(StereoCorrection, SameFramePairFactorAndJacobians) {
  std::mt19937 rng(20);
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(0.8, 12.0);
  const PoseManifold pm;
  for (int trial = 0; trial < 60; ++trial) {
    const Pose S0 = randomPose(rng, 0.005, 0.001), S = randomPose(rng, 0.005, 0.001);
    const Vec2 uv_l(0.5 * u(rng), 0.4 * u(rng));
    double rho = 1.0 / depth(rng);
    const Vec3 p_C1 = (cam1() * S).inverse() * (cam0() * (Vec3(uv_l.x(), uv_l.y(), 1.0) / rho));
    const Vec2 uv_r = p_C1.head<2>() / p_C1.z() + Vec2(u(rng), u(rng)) * (1.5 / kFocal);
    const double si = pointSqrtInformation(kFocal);
    // Built with S0 in cam1's extrinsics; evaluated at S it is the plain factor with cam1 at T_B_C1 * S.
    const PointStereoFactor built(uv_l, uv_r, cam0(), cam1() * S0, si);
    const PointStereoCorrectedFactor f(built, S0);
    const PointStereoCorrectedFactor g(uv_l, uv_r, cam0(), cam1() * S0, S0, si);
    const PointStereoFactor direct(uv_l, uv_r, cam0(), cam1() * S, si);
    auto bs = block(S);
    const double* pw[2] = {&rho, bs.data()};
    const double* pd[1] = {&rho};
    double rf[2], rg[2], rd[2];
    ASSERT_TRUE(f.Evaluate(pw, rf, nullptr));
    ASSERT_TRUE(g.Evaluate(pw, rg, nullptr));
    ASSERT_TRUE(direct.Evaluate(pd, rd, nullptr));
    EXPECT_NEAR(rf[0], rd[0], 1e-9);
    EXPECT_NEAR(rf[1], rd[1], 1e-9);
    EXPECT_NEAR(rg[0], rd[0], 1e-9);
    EXPECT_NEAR(rg[1], rd[1], 1e-9);
    EXPECT_EQ(f.parameter_block_sizes(), (std::vector<int32_t>{1, 7}));
    const std::vector<double*> params = {&rho, bs.data()};
    ASSERT_TRUE(testing::jacobiansMatch(f, params, {nullptr, &pm}, kTol)) << "trial " << trial;
    if (trial == 0) {
      for (auto [b, entry] : {std::pair{0, 0}, std::pair{0, 1}, std::pair{1, 2}, std::pair{1, 7 + 4}}) {
        const CorruptEntry bad(f, b, entry);
        EXPECT_FALSE(testing::checkJacobians(bad, params, {nullptr, &pm}).ok(kTol)) << b << " " << entry;
      }
    }
  }
}

TEST(TangentJacobiansCache, GivesWhatTheCrossCastGivesForEachType) {
  std::mt19937 rng(5);
  std::vector<std::shared_ptr<ceres::CostFunction>> costs;
  for (int k = 0; k < 3; ++k) {  // several objects of each type, interleaved
    const PointCase c = pointCase(rng, cam1());
    const LineCase l = lineCase(rng, c.T_W_Bi * cam0());
    auto point = std::make_shared<PointReprojectionFactor>(c.uv_host, c.uv_target, cam0(), cam1(), kFocal);
    costs.push_back(point);
    costs.push_back(std::make_shared<LineReprojectionFactor>(l.s, l.e, cam0(), kFocal));
    costs.push_back(std::make_shared<RigCorrectedFactor>(point, std::vector<int>{0, 1}, c.T_B_R0));
    costs.push_back(std::make_shared<ZeroVelocityFactor>(0.1));  // not a TangentJacobians
  }
  TangentJacobiansCache cache;
  for (int pass = 0; pass < 2; ++pass)
    for (const auto& cost : costs) EXPECT_EQ(cache.of(cost.get()), dynamic_cast<const TangentJacobians*>(cost.get()));
  EXPECT_EQ(cache.of(nullptr), nullptr);
}

}  // namespace
}  // namespace linnet
