// System tests of the Estimator on the synthetic stereo-inertial world (known ground truth, no images).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <gtest/gtest.h>

#include "estimator/estimator_test_util.h"
#include "linnet/core/error.h"

namespace linnet::testing {
namespace {

void report(const char* name, const RunResult& r) {
  std::printf("[%s] frames %zu, first pose at %d, APE %.4f m, solve ms median %.2f p95 %.2f max %.2f\n", name,
              r.outputs.size(), r.first_pose, r.ape_rmse, r.median_ms, r.p95_ms, r.max_ms);
  if (std::getenv("LINNET_TEST_VERBOSE") != nullptr) {
    for (std::size_t i = 0; i < r.errors.size(); i += 20) std::printf("  error[%zu] = %.4f m\n", i, r.errors[i]);
  }
}

TEST(EstimatorSynthetic, MovingStartInitialisesAndTracksAccurately) {
  SyntheticOptions so;
  so.duration_s = 20.0;
  so.pixel_noise = 0.2;
  SyntheticVio sim(so);
  const RunResult r = runEstimator(sim, EstimatorOptions());
  report("moving", r);
  ASSERT_GE(r.first_pose, 0);
  EXPECT_LE(r.first_pose, 20) << "initialised within 1 s of frames";
  for (std::size_t k = static_cast<std::size_t>(r.first_pose); k < r.outputs.size(); ++k) {
    EXPECT_TRUE(r.outputs[k].has_pose) << "frame " << k;
    EXPECT_EQ(r.outputs[k].status, TrackingStatus::kTracking) << "frame " << k;
  }
  EXPECT_EQ(r.outputs.back().reinitialisations, 0);
  EXPECT_LT(r.ape_rmse, 0.02);
  EXPECT_GT(r.outputs.back().num_points, 30);
  // The moving initialiser's gyroscope bias (visual vs preintegrated rotations) is already close.
  EXPECT_LT((r.outputs[static_cast<std::size_t>(r.first_pose)].b_g - so.gyr_bias).norm(), 2e-3);
}

// A moving start collects init.moving_frames frames before its first solve; a window_size below that must still
// hold: the window keeps window_size frames plus the newest from the first slide on, not moving_frames for the run.
TEST(EstimatorSynthetic, WindowSizeHoldsAfterAMovingStart) {
  SyntheticOptions so;
  so.duration_s = 3.0;
  SyntheticVio sim(so);
  for (int window : {3, 5, 8}) {
    EstimatorOptions o;
    o.window_size = window;
    ASSERT_GT(o.init.moving_frames, 3 + 1);
    std::size_t largest = 0;
    const RunResult r = runEstimator(sim, o, true, [](int, FrameObservations*) {},
                                     [&](const Estimator& est, const EstimatorOutput& out) {
                                       if (out.has_pose) largest = std::max(largest, est.windowPoses().size());
                                     });
    const auto with_pose = std::count_if(r.outputs.begin(), r.outputs.end(),
                                         [](const EstimatorOutput& out) { return out.has_pose; });
    EXPECT_GT(with_pose, 30) << "window " << window;
    EXPECT_EQ(largest, static_cast<std::size_t>(window + 1)) << "window " << window;
  }
}

TEST(EstimatorSynthetic, AtRestTheEstimateStaysStill) {
  SyntheticOptions so;
  so.duration_s = 6.0;
  so.static_s = 100.0;  // never starts moving
  so.imu_noise = true;
  so.pixel_noise = 0.1;
  SyntheticVio sim(so);
  const RunResult r = runEstimator(sim, EstimatorOptions());
  report("at rest", r);
  ASSERT_EQ(r.first_pose, 0);
  double path = 0.0;
  int keyframes = 0;
  for (std::size_t k = 1; k < r.outputs.size(); ++k) {
    path += (r.outputs[k].T_W_B.p - r.outputs[k - 1].T_W_B.p).norm();
    keyframes += r.outputs[k].keyframe ? 1 : 0;
    EXPECT_EQ(r.outputs[k].status, TrackingStatus::kTracking);
  }
  const double drift = (r.outputs.back().T_W_B.p - r.outputs.front().T_W_B.p).norm();
  std::printf("[at rest] drift %.5f m, path length %.5f m over %zu frames, %d keyframes\n", drift, path,
              r.outputs.size(), keyframes);
  EXPECT_LT(drift, 0.003);
  EXPECT_LT(path, 0.015);  // frame-to-frame jitter (noisy IMU, 0.1 px): 5 mm in all with the rest priors
                           // (zero_velocity), about 0.3 mm per frame without
  // No parallax at rest: keyframes only from the time-gap rule (every 2 s).
  EXPECT_LE(keyframes, 3);
}

TEST(EstimatorSynthetic, NoisyImuStaysAccurate) {
  SyntheticOptions so;
  so.duration_s = 20.0;
  so.imu_noise = true;
  so.pixel_noise = 0.5;
  so.seed = 11;
  SyntheticVio sim(so);
  const RunResult r = runEstimator(sim, EstimatorOptions());
  report("noisy", r);
  ASSERT_GE(r.first_pose, 0);
  EXPECT_EQ(r.outputs.back().reinitialisations, 0);
  EXPECT_LT(r.ape_rmse, 0.05);
  // The accelerometer and gyroscope biases are estimated.
  const Vec3 bg_err = r.outputs.back().b_g - so.gyr_bias;
  EXPECT_LT(bg_err.norm(), 2e-3);
}

TEST(EstimatorSynthetic, BothSolverEnginesTrackNoisyData) {
  // The default engine (schur_lm) and Ceres solve the same window problems: both stay accurate on the same data.
  SyntheticOptions so;
  so.duration_s = 15.0;
  so.imu_noise = true;
  so.pixel_noise = 0.5;
  so.seed = 5;
  SyntheticVio sim(so);
  double ape[2] = {0.0, 0.0};
  int k = 0;
  for (const char* engine : {"schur_lm", "ceres"}) {
    EstimatorOptions o;
    o.solver.engine = engine;
    const RunResult r = runEstimator(sim, o);
    report(engine, r);
    ASSERT_GE(r.first_pose, 0) << engine;
    EXPECT_EQ(r.outputs.back().reinitialisations, 0) << engine;
    EXPECT_LT(r.ape_rmse, 0.05) << engine;
    ape[k++] = r.ape_rmse;
  }
  // With three iterations per frame both converge (schur_lm starts nearly Gauss-Newton, Ceres uses dogleg).
  EXPECT_LT(std::abs(ape[0] - ape[1]), 0.002);
}

TEST(EstimatorSynthetic, StaticStartInitialisesAtOnceFromGravity) {
  SyntheticOptions so;
  so.duration_s = 10.0;
  so.static_s = 2.0;  // at rest for the first second of frames, then a smooth ramp into motion
  SyntheticVio sim(so);
  const RunResult r = runEstimator(sim, EstimatorOptions());
  report("static start", r);
  ASSERT_EQ(r.first_pose, 0) << "a static start initialises on the first frame";
  const EstimatorOutput& first = r.outputs.front();
  EXPECT_LT(first.v_W.norm(), 1e-9);
  // Roll and pitch from gravity: the body's x axis is up in this world.
  const Vec3 up_est = first.T_W_B.R().col(0), up_true = sim.truth(first.t).T_W_B.R().col(0);
  EXPECT_LT(std::acos(std::min(1.0, up_est.dot(up_true))), 0.01);
  EXPECT_LT((first.b_g - so.gyr_bias).norm(), 1e-3);
  EXPECT_EQ(r.outputs.back().reinitialisations, 0);
  EXPECT_LT(r.ape_rmse, 0.02);
}

// Stamps 5 ms after the capture and extrinsics off by 0.3 deg / 3 mm (a rough calibration), 20 s of motion.
SyntheticOptions roughCalibrationWorld(int seed) {
  SyntheticOptions so;
  so.duration_s = 20.0;
  so.imu_noise = true;
  so.pixel_noise = 0.3;
  so.seed = seed;
  so.camera_time_offset_s = 0.005;
  so.calibration_error = Pose(expSO3(Vec3(0.2, -0.15, 0.15) * (M_PI / 180.0)), Vec3(0.002, -0.002, 0.001));
  return so;
}

EstimatorOptions calibrationEstimated() {
  EstimatorOptions o;
  o.extrinsics.estimate = true;
  o.extrinsics.estimate_stereo = false;
  o.time_offset.estimate = true;
  return o;
}

TEST(EstimatorSynthetic, OnlineCalibrationRecoversTimeOffsetAndExtrinsics) {
  // Estimated online, the offset and the rotation are recovered. cam1 is exact here, so its correction is off: on
  // this short run with far points (5-9 m) the freedom alone costs 1 mm.
  const SyntheticOptions so = roughCalibrationWorld(21);
  const double rot_err_deg = logSO3(so.calibration_error.q).norm() * 180.0 / M_PI;
  SyntheticVio sim(so);
  EstimatorOptions o = calibrationEstimated();
  const RunResult r = runEstimator(sim, o);
  report("calibration estimated", r);
  ASSERT_GE(r.first_pose, 0);
  EXPECT_EQ(r.outputs.back().reinitialisations, 0);
  const EstimatorOutput& last = r.outputs.back();
  // Ideal correction: the inverse of the error (cameras at T_B_R * error * T_B_Ci).
  const Vec3 rot_left = logSO3(last.T_B_R.q * so.calibration_error.q) * (180.0 / M_PI);
  std::printf("[calibration] t_d %.3f ms (true 5), rotation error left %.3f deg (was %.3f), translation left %.2f mm\n",
              1e3 * last.time_offset_s, rot_left.norm(), rot_err_deg,
              1e3 * (last.T_B_R * so.calibration_error).p.norm());
  std::printf("[calibration] cam1 correction %.4f deg, %.3f mm\n", logSO3(last.S_C1.q).norm() * 180.0 / M_PI,
              1e3 * last.S_C1.p.norm());
  EXPECT_NEAR(last.time_offset_s, 0.005, 0.0005);
  EXPECT_LT(rot_left.norm(), 0.4 * rot_err_deg);  // 0.09 of 0.29 deg left (the prior is 0.1 deg)

  // Estimated in every solve instead of only the keyframes' (solver.calibration_on_keyframes, the default: the other
  // solves hold it, without the calibration wrappers): the same calibration and trajectory within noise.
  EstimatorOptions every = o;
  every.solver.calibration_on_keyframes = false;
  const RunResult e = runEstimator(sim, every);
  report("calibration in every solve", e);
  const EstimatorOutput& last_e = e.outputs.back();
  EXPECT_NEAR(last.time_offset_s, last_e.time_offset_s, 0.0003);
  EXPECT_LT(logSO3(last.T_B_R.q.conjugate() * last_e.T_B_R.q).norm() * 180.0 / M_PI, 0.05);
  EXPECT_LT(r.ape_rmse, 1.2 * e.ape_rmse);
  EXPECT_LT(e.ape_rmse, 1.2 * r.ape_rmse);

  // Held after 8 s (the frames' capture shift instead of the estimated block): the offset stops moving and the
  // trajectory stays as good.
  o.time_offset.estimate_for_s = 8.0;
  const RunResult held = runEstimator(sim, o);
  report("offset held after 8 s", held);
  EXPECT_EQ(held.outputs.back().time_offset_s, held.outputs[held.outputs.size() - 100].time_offset_s);
  EXPECT_NEAR(held.outputs.back().time_offset_s, 0.005, 0.0005);
  EXPECT_LT(held.ape_rmse, 1.2 * r.ape_rmse);
}

TEST(EstimatorSynthetic, OnlineExtrinsicsLowerTheMeanErrorOverSeeds) {
  // With the extrinsics estimated too, the trajectory is better on average than with only the offset estimated.
  // Per seed the gain is noisy (APE ratio estimated / trusted 0.82-1.10 over seeds 21-28 with a window of 6
  // keyframes, 0.79-1.08 with 7), so it is checked on the sum over eight seeds: ratio 0.964 with 6, 0.924 with 7
  // (seed 21 alone: 1.003 with 6, 0.792 with 7). Each seed's calibration is recovered as well.
  double trusted_sum = 0.0, estimated_sum = 0.0;
  for (int seed = 21; seed <= 28; ++seed) {
    const SyntheticOptions so = roughCalibrationWorld(seed);
    SyntheticVio sim(so);
    EstimatorOptions offset_only;
    offset_only.extrinsics.estimate = false;
    const RunResult trusted = runEstimator(sim, offset_only);
    const RunResult r = runEstimator(sim, calibrationEstimated());
    ASSERT_GE(r.first_pose, 0) << "seed " << seed;
    const double rot_left = logSO3(r.outputs.back().T_B_R.q * so.calibration_error.q).norm() * 180.0 / M_PI;
    std::printf("[seed %d] APE offset only %.2f mm, with the extrinsics %.2f mm; rotation left %.3f deg\n", seed,
                1e3 * trusted.ape_rmse, 1e3 * r.ape_rmse, rot_left);
    EXPECT_LT(rot_left, 0.15) << "seed " << seed;  // of 0.29 deg
    trusted_sum += trusted.ape_rmse;
    estimated_sum += r.ape_rmse;
  }
  std::printf("[calibration over seeds] APE ratio with the extrinsics estimated %.3f\n", estimated_sum / trusted_sum);
  EXPECT_LT(estimated_sum, trusted_sum);
}

TEST(EstimatorSynthetic, OnlineStereoCorrectionRecoversCam1) {
  // cam1 off by a few hundredths of a degree relative to cam0 (0.05 deg of yaw biases every disparity by 0.4 px, a
  // 5 % depth error at 7 m): refined online with the rig (from 10 s of motion on, by default), most of it is recovered
  // and the trajectory is better.
  SyntheticOptions so;
  so.duration_s = 30.0;
  so.imu_noise = true;
  so.pixel_noise = 0.3;
  so.seed = 22;
  const Vec3 rot_err = Vec3(0.02, 0.05, -0.03) * (M_PI / 180.0);
  so.stereo_error = Pose(expSO3(rot_err), Vec3::Zero());
  SyntheticVio sim(so);
  EstimatorOptions trusted_options;
  trusted_options.extrinsics.estimate_stereo = false;
  const RunResult trusted = runEstimator(sim, trusted_options);
  const RunResult r = runEstimator(sim, EstimatorOptions());
  report("stereo trusted", trusted);
  report("stereo estimated", r);
  ASSERT_GE(r.first_pose, 0);
  EXPECT_EQ(r.outputs.back().reinitialisations, 0);
  // Ideal: S = stereo_error^-1 (cam1 at T_B_C1 * stereo_error * S = T_B_C1).
  const Vec3 left = logSO3(so.stereo_error.q * r.outputs.back().S_C1.q) * (180.0 / M_PI);
  std::printf("[stereo] cam1 rotation error left %.4f deg (was %.4f)\n", left.norm(), rot_err.norm() * 180.0 / M_PI);
  EXPECT_LT(left.norm(), 0.4 * rot_err.norm() * 180.0 / M_PI);
  EXPECT_LT(r.ape_rmse, 0.8 * trusted.ape_rmse);
  EXPECT_TRUE(trusted.outputs.back().S_C1.q.isApprox(Quat::Identity()));
}

TEST(EstimatorSynthetic, TwoRunsAreBitIdentical) {
  SyntheticOptions so;
  so.duration_s = 5.0;
  so.imu_noise = true;
  SyntheticVio sim(so);
  EstimatorOptions o;
  o.solver.max_solver_time_s = 100.0;  // the iteration bound decides, never the clock
  const RunResult a = runEstimator(sim, o), b = runEstimator(sim, o);
  ASSERT_EQ(a.outputs.size(), b.outputs.size());
  for (std::size_t k = 0; k < a.outputs.size(); ++k) {
    const EstimatorOutput &x = a.outputs[k], &y = b.outputs[k];
    ASSERT_EQ(x.has_pose, y.has_pose) << k;
    EXPECT_EQ(x.T_W_B.p, y.T_W_B.p) << k;
    EXPECT_EQ(x.T_W_B.q.coeffs(), y.T_W_B.q.coeffs()) << k;
    EXPECT_EQ(x.v_W, y.v_W) << k;
    EXPECT_EQ(x.b_a, y.b_a) << k;
    EXPECT_EQ(x.b_g, y.b_g) << k;
    EXPECT_EQ(x.num_points, y.num_points) << k;
  }
}

TEST(EstimatorSynthetic, FailureResetsAndReinitialisesContinuously) {
  SyntheticOptions so;
  so.duration_s = 12.0;
  SyntheticVio sim(so);
  // Frames 100..104 arrive without any point: too few tracked points -> failure, reset, re-initialisation.
  const RunResult r = runEstimator(sim, EstimatorOptions(), true, [](int k, FrameObservations* obs) {
    if (k >= 100 && k < 105) obs->points.clear();
  });
  report("failure", r);
  ASSERT_GE(r.first_pose, 0);
  EXPECT_GE(r.outputs.back().reinitialisations, 1);
  bool lost = false;
  for (std::size_t k = static_cast<std::size_t>(r.first_pose); k < r.outputs.size(); ++k) {
    EXPECT_TRUE(r.outputs[k].has_pose) << "output continues at frame " << k;
    lost = lost || r.outputs[k].status == TrackingStatus::kLost;
  }
  EXPECT_TRUE(lost);
  EXPECT_EQ(r.outputs.back().status, TrackingStatus::kTracking);
  // Continuous: no step larger than the motion between two frames allows (speed < 2 m/s here, 50 ms apart).
  EXPECT_LT(r.max_step_m, 0.15);
  EXPECT_LT(r.ape_rmse, 0.10);
}

TEST(EstimatorSynthetic, MonocularDoesNotCrash) {
  SyntheticOptions so;
  so.duration_s = 3.0;
  so.stereo = false;
  SyntheticVio sim(so);
  const RunResult r = runEstimator(sim, EstimatorOptions(), false);
  EXPECT_EQ(r.outputs.size(), sim.frames().size());
  for (const EstimatorOutput& o : r.outputs) EXPECT_NE(o.status, TrackingStatus::kLost);
}

TEST(EstimatorSynthetic, RejectsFramesOutOfOrderAndBadOptions) {
  Estimator est(EstimatorOptions(), ImuNoise(), eurocTBC0(), eurocTBC1());
  FrameObservations a;
  a.t = 1'000'000'000;
  est.addFrame(a);
  EXPECT_THROW(est.addFrame(a), UsageError);
  EstimatorOptions bad;
  bad.solver.outlier_px = -1.0;
  try {
    Estimator e(bad, ImuNoise(), eurocTBC0(), eurocTBC1());
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("estimator.solver.outlier_px"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace linnet::testing
