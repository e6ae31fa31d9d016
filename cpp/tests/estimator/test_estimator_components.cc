// Unit tests of the estimator's building blocks: keyframe policy, PnP, window sliding, point landmarks.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "estimator/synthetic_vio.h"
#include "linnet/core/error.h"
#include "linnet/estimator/factors/prior_factor.h"
#include "linnet/estimator/initial_prior.h"
#include "linnet/estimator/keyframe_policy.h"
#include "linnet/estimator/manifolds.h"
#include "linnet/estimator/pnp.h"
#include "linnet/estimator/point_landmarks.h"
#include "linnet/estimator/window.h"

namespace linnet::testing {
namespace {

TEST(KeyframePolicy, ThesisCases) {
  KeyframeOptions o;
  KeyframeInputs in;
  in.tracked = 100;
  in.dt_s = 0.1;
  // Static: no parallax -> no keyframe.
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kNone);
  // Pure rotation (small P, large Q) with (uncompensated) parallax -> no keyframe.
  in.parallax_px = 30.0;
  in.rotation_rad = 0.6;
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kNone);
  // Small P, small Q, parallax -> keyframe.
  in.rotation_rad = 0.05;
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kParallax);
  // Translation with parallax -> keyframe, whatever the rotation; without parallax -> none.
  in.translation_m = 0.5;
  in.rotation_rad = 0.6;
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kParallax);
  in.parallax_px = 2.0;
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kNone);
  // Too few tracked points or a long gap force one.
  in.tracked = 3;
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kTooFewTracked);
  in.tracked = 100;
  in.dt_s = 5.0;
  EXPECT_EQ(keyframeDecision(o, in), KeyframeReason::kTimeGap);
}

TEST(KeyframePolicy, CompensatedParallaxCancelsPureRotation) {
  const Mat3 R = expSO3(Vec3(0.02, -0.1, 0.05)).toRotationMatrix();
  std::vector<std::pair<Vec2, Vec2>> corr;
  for (int i = 0; i < 20; ++i) {
    const Vec3 ray(0.03 * i - 0.3, 0.2 - 0.02 * i, 1.0);
    const Vec3 r2 = R * ray;
    corr.emplace_back(ray.head<2>(), r2.head<2>() / r2.z());
  }
  EXPECT_LT(compensatedParallaxPx(corr, R, 460.0), 1e-9);
  EXPECT_GT(compensatedParallaxPx(corr, Mat3::Identity(), 460.0), 10.0);
}

TEST(Pnp, RecoversPoseFromPerturbedGuessWithOutliers) {
  const Pose T_B_C0 = eurocTBC0();
  const Pose truth(expSO3(Vec3(0.1, -0.2, 0.3)), Vec3(0.5, -0.2, 1.0));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Vec3> p_W;
  std::vector<Vec2> uv;
  const Pose T_W_C = truth * T_B_C0;
  for (int i = 0; i < 60; ++i) {
    const Vec3 p_C(2.0 * u(rng), 1.5 * u(rng), 4.0 + 2.0 * u(rng));
    p_W.push_back(T_W_C * p_C);
    uv.push_back(p_C.head<2>() / p_C.z());
  }
  for (int i = 0; i < 5; ++i) uv[static_cast<std::size_t>(i)] += Vec2(0.05, -0.04);  // gross outliers (~20 px)
  Pose T = Pose(truth.q * expSO3(Vec3(0.03, -0.02, 0.04)), truth.p + Vec3(0.1, -0.05, 0.08));
  const PnpResult r = refinePosePnp(p_W, uv, T_B_C0, 460.0, 3.0, &T);
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.inliers, 55);
  EXPECT_LT(r.rms_px, 1e-6);
  EXPECT_LT((T.p - truth.p).norm(), 1e-6);
  EXPECT_LT(logSO3(T.q.conjugate() * truth.q).norm(), 1e-6);
}

TEST(Window, IdsKeysAndSliding) {
  Window w;
  ImuNoise noise;
  for (int k = 0; k < 4; ++k) {
    WindowFrame& f = w.push(1'000'000'000LL + k * 50'000'000LL);
    if (k > 0) {
      std::vector<ImuSample> s;
      for (int i = 0; i <= 10; ++i) {
        ImuSample m;
        m.t = f.t - 50'000'000LL + i * 5'000'000LL;
        m.acc = Vec3(0.1 * k, 9.81, 0.0);
        m.gyr = Vec3(0.01, 0.02 * k, 0.0);
        s.push_back(m);
      }
      f.preint = std::make_unique<Preintegration>(s, noise, Vec3::Zero(), Vec3::Zero());
    }
  }
  EXPECT_EQ(w.size(), 4);
  EXPECT_EQ(w.indexOf(2), 2);
  EXPECT_EQ(w.block(frameBlockKey(2, BlockKind::kPose)), w[2].pose.data());
  EXPECT_EQ(w.block(frameBlockKey(2, BlockKind::kSpeedBias)), w[2].speed_bias.data());
  // Merging frame 2 into 3: the newest preintegration then spans frames 1 -> 3.
  w.removeMerging(2);
  EXPECT_EQ(w.size(), 3);
  EXPECT_EQ(w.indexOf(2), -1);
  EXPECT_EQ(w.block(frameBlockKey(2, BlockKind::kPose)), nullptr);
  EXPECT_NEAR(w[2].preint->sumDt(), 0.1, 1e-12);
  w.popOldest();
  EXPECT_EQ(w[0].id, 1);
  EXPECT_EQ(w[0].preint, nullptr);
  EXPECT_THROW(w.removeMerging(0), UsageError);
}

TEST(Window, CamerasAreTheInversesOfEachFramesCameraPose) {
  // The outlier checks read each frame's world -> camera pose from WindowCameras instead of inverting T_W_B * T_B_C
  // at every sighting: the same numbers, bit for bit, and none for frames that left the window.
  Window w;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 5; ++k) {
    WindowFrame& f = w.push(1'000'000'000LL + k * 50'000'000LL);
    f.setPose(Pose(Quat(Eigen::AngleAxisd(u(rng), Vec3(u(rng), u(rng), 1.0).normalized())), Vec3(u(rng), u(rng), u(rng))));
  }
  w.removeMerging(2);
  const Pose T_B_C0(Quat(Eigen::AngleAxisd(0.3, Vec3::UnitY())), Vec3(0.02, -0.06, 0.01));
  const Pose T_B_C1(Quat(Eigen::AngleAxisd(0.31, Vec3::UnitY())), Vec3(0.02, 0.05, 0.01));
  const WindowCameras cams(w, T_B_C0, T_B_C1);
  for (int i = 0; i < w.size(); ++i) {
    const Pose c0 = (w[i].T_W_B() * T_B_C0).inverse(), c1 = (w[i].T_W_B() * T_B_C1).inverse();
    ASSERT_NE(cams.cam0(w[i].id), nullptr);
    ASSERT_NE(cams.cam1(w[i].id), nullptr);
    EXPECT_EQ(cams.cam0(w[i].id)->p, c0.p);
    EXPECT_EQ(cams.cam0(w[i].id)->q.coeffs(), c0.q.coeffs());
    EXPECT_EQ(cams.cam1(w[i].id)->p, c1.p);
    EXPECT_EQ(cams.cam1(w[i].id)->q.coeffs(), c1.q.coeffs());
  }
  EXPECT_EQ(cams.cam0(2), nullptr);
  EXPECT_EQ(cams.cam0(7), nullptr);
  const WindowCameras mono(w, T_B_C0, std::nullopt);
  EXPECT_NE(mono.cam0(w[0].id), nullptr);
  EXPECT_EQ(mono.cam1(w[0].id), nullptr);
}

TEST(PointLandmarks, StereoTriangulationReanchoringAndResidualKinds) {
  const Pose T_B_C0 = eurocTBC0(), T_B_C1 = eurocTBC1();
  Window w;
  w.push(0).setPose(Pose(Quat::Identity(), Vec3::Zero()));
  w.push(1).setPose(Pose(expSO3(Vec3(0.0, 0.05, 0.0)), Vec3(0.0, 0.3, 0.0)));
  const Vec3 p_W(0.3, -0.2, 5.0);
  auto observation = [&](const WindowFrame& f, bool right) {
    PointObservation o;
    o.id = 42;
    const Vec3 c0 = (f.T_W_B() * T_B_C0).inverse() * p_W, c1 = (f.T_W_B() * T_B_C1).inverse() * p_W;
    o.uv0 = c0.head<2>() / c0.z();
    o.has_right = right;
    o.uv1 = c1.head<2>() / c1.z();
    return std::vector<PointObservation>{o};
  };
  SolverOptions so;
  so.right_residuals_all_frames = true;
  {
    // Default: cam1 only through the host frame's left-right residual (kind 3), the other frame by kind 1.
    PointLandmarks lean(SolverOptions(), T_B_C0, T_B_C1);
    lean.observe(w[0].id, observation(w[0], true));
    EXPECT_EQ(lean.triangulate(w), 1);
    lean.observe(w[1].id, observation(w[1], true));
    const std::vector<ResidualSpec> r = lean.residuals(w);
    ASSERT_EQ(r.size(), 2u);
    EXPECT_EQ(r[0].blocks.size(), 1u);
    EXPECT_EQ(r[1].blocks.size(), 3u);
    // A landmark seen in fewer than min_observations frames stays out of the solve.
    SolverOptions three;
    three.min_observations = 3;
    PointLandmarks strict(three, T_B_C0, T_B_C1);
    strict.observe(w[0].id, observation(w[0], true));
    strict.triangulate(w);
    strict.observe(w[1].id, observation(w[1], true));
    EXPECT_TRUE(strict.residuals(w).empty());
    EXPECT_EQ(strict.countUsed(), 0);
  }
  PointLandmarks lms(so, T_B_C0, T_B_C1);
  lms.observe(w[0].id, observation(w[0], true));
  EXPECT_EQ(lms.triangulate(w), 1);
  lms.observe(w[1].id, observation(w[1], true));
  EXPECT_LT((lms.worldPosition(w, lms.all().at(42)) - p_W).norm(), 1e-6);
  // Seen from frame 1, hosted by frame 0: counted for frame 1 only, as triangulatedIn lists it.
  for (int i = 0; i < 2; ++i) {
    std::vector<Vec3> positions;
    std::vector<Vec2> uv;
    lms.triangulatedIn(w, w[i].id, &positions, &uv);
    EXPECT_EQ(lms.countTriangulatedFromElsewhere(w[i].id), static_cast<int>(positions.size()));
    EXPECT_EQ(lms.countTriangulatedFromElsewhere(w[i].id), i);
  }
  // right_residuals_all_frames: host frame: kind 3; the other frame: kinds 1 and 2.
  const std::vector<ResidualSpec> r = lms.residuals(w);
  ASSERT_EQ(r.size(), 3u);
  EXPECT_EQ(r[0].blocks.size(), 1u);
  EXPECT_EQ(r[1].blocks.size(), 3u);
  EXPECT_EQ(lms.countUsed(), 1);
  EXPECT_EQ(lms.rejectOutliers(w), 0);
  // Removing the host re-anchors the point in frame 1 at the same world position.
  lms.removeFrame(w, w[0].id);
  const PointLandmark& lm = lms.all().at(42);
  EXPECT_EQ(lm.host, w[1].id);
  EXPECT_LT((lms.worldPosition(w, lm) - p_W).norm(), 1e-6);
}

}  // namespace
}  // namespace linnet::testing

namespace linnet::testing {
namespace {

TEST(InitialPrior, PinsPositionAndYawButNotTilt) {
  WindowFrame f;
  f.id = 3;
  f.setPose(Pose(expSO3(Vec3(0.3, -0.2, 1.0)), Vec3(1.0, 2.0, 3.0)));
  f.setV(Vec3(0.1, 0.2, 0.3));
  PoseManifold manifold;
  InitialPriorSigmas s;
  s.velocity = 0.05;
  const auto prior = makeInitialPrior(f, s, &manifold);
  ASSERT_EQ(prior->keys.size(), 2u);
  EXPECT_EQ(prior->keys[0], frameBlockKey(3, BlockKind::kPose));
  PriorFactor factor(prior);
  auto evaluate = [&](const Pose& T, const Vec3& v) {
    WindowFrame g;
    g.pose = f.pose;
    g.speed_bias = f.speed_bias;
    g.setPose(T);
    g.setV(v);
    const double* blocks[2] = {g.pose.data(), g.speed_bias.data()};
    Eigen::VectorXd r(factor.num_residuals());
    EXPECT_TRUE(factor.Evaluate(blocks, r.data(), nullptr));
    return r;
  };
  const Pose T = f.T_W_B();
  EXPECT_LT(evaluate(T, f.v()).norm(), 1e-12);
  // A rotation about z of W (yaw) and a position change are penalised; a tilt is not.
  const double eps = 1e-4;
  const Eigen::VectorXd r_yaw = evaluate(Pose(expSO3(Vec3(0, 0, eps)) * T.q, T.p), f.v());
  EXPECT_NEAR(r_yaw.norm(), eps / s.yaw_rad, 1e-3 * eps / s.yaw_rad);
  const Eigen::VectorXd r_tilt = evaluate(Pose(expSO3(Vec3(eps, 0, 0)) * T.q, T.p), f.v());
  EXPECT_LT(r_tilt.norm(), 1e-6 * eps / s.yaw_rad);
  const Eigen::VectorXd r_pos = evaluate(Pose(T.q, T.p + Vec3(0, eps, 0)), f.v());
  EXPECT_NEAR(r_pos.norm(), eps / s.position_m, 1e-6 * eps / s.position_m);
  const Eigen::VectorXd r_vel = evaluate(T, f.v() + Vec3(eps, 0, 0));
  EXPECT_NEAR(r_vel.norm(), eps / s.velocity, 1e-9);
}

}  // namespace
}  // namespace linnet::testing
