// Preintegration on real data: EuRoC V1_01_easy IMU (ADIS16448, 200 Hz) against the vicon2gt ground truth
// (state_groundtruth_estimate0: p, q (w, x, y, z), v, b_w, b_a at 20 Hz). 1 s windows across the whole
// sequence, integrated with the ground-truth biases at the window start, predicted from the ground-truth
// state.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "linnet/imu/gravity_alignment.h"
#include "linnet/imu/imu_buffer.h"
#include "linnet/imu/preintegration.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

// Parses a numeric EuRoC csv (comment lines start with '#'); the first column is an int64 ns time stamp.
struct CsvRow {
  Timestamp t = 0;
  std::vector<double> v;
};

std::vector<CsvRow> readCsv(const std::filesystem::path& path, size_t columns) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  std::vector<CsvRow> rows;
  std::string line;
  long number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (line.empty() || line[0] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream ss(line);
    CsvRow row;
    ss >> row.t;
    double x;
    while (ss >> x) row.v.push_back(x);
    if (row.v.size() + 1 != columns)
      throw std::runtime_error(path.string() + ":" + std::to_string(number) + ": expected " +
                               std::to_string(columns) + " columns");
    rows.push_back(std::move(row));
  }
  return rows;
}

ImuState groundTruthState(const CsvRow& r) {
  ImuState s;
  s.t = r.t;
  s.T_W_B = Pose(Quat(r.v[3], r.v[4], r.v[5], r.v[6]), Vec3(r.v[0], r.v[1], r.v[2]));  // EuRoC: w, x, y, z
  s.v_W = Vec3(r.v[7], r.v[8], r.v[9]);
  s.b_g = Vec3(r.v[10], r.v[11], r.v[12]);
  s.b_a = Vec3(r.v[13], r.v[14], r.v[15]);
  return s;
}

double percentile(std::vector<double> x, double p) {
  std::sort(x.begin(), x.end());
  return x[static_cast<size_t>(p * static_cast<double>(x.size() - 1))];
}

TEST(PreintegrationEuroc, OneSecondWindowsMatchGroundTruth) {
  const auto mav = testing::eurocMicroDir() / "mav0";
  LINNET_REQUIRE_SHARED_DATA(mav / "imu0" / "data.csv");
  LINNET_REQUIRE_SHARED_DATA(mav / "state_groundtruth_estimate0" / "data.csv");

  ImuBuffer buffer;
  for (const CsvRow& r : readCsv(mav / "imu0" / "data.csv", 7))
    buffer.append({r.t, Vec3(r.v[3], r.v[4], r.v[5]), Vec3(r.v[0], r.v[1], r.v[2])});  // csv: gyro, then acc
  const std::vector<CsvRow> gt = readCsv(mav / "state_groundtruth_estimate0" / "data.csv", 17);
  ASSERT_GT(gt.size(), 100u);

  ImuNoise noise;  // EuRoC defaults
  struct Window {
    ImuState s0, s1;
    Preintegration pre;
    Preintegration raw;  // linearised at zero bias, for the no-bias comparison
  };
  std::vector<Window> windows;
  constexpr size_t kWindow = 20;  // GT rows: 1 s at 20 Hz
  constexpr size_t kStride = 30;  // a window every 1.5 s
  for (size_t i = 0; i + kWindow < gt.size(); i += kStride) {
    const ImuState s0 = groundTruthState(gt[i]);
    const ImuState s1 = groundTruthState(gt[i + kWindow]);
    if (!buffer.covers(s0.t, s1.t)) continue;
    const auto samples = buffer.samplesBetween(s0.t, s1.t);
    windows.push_back({s0, s1, Preintegration(samples, noise, s0.b_a, s0.b_g),
                       Preintegration(samples, noise, Vec3::Zero(), Vec3::Zero())});
  }
  ASSERT_GE(windows.size(), 80u);

  // The vicon2gt world frame is not exactly gravity-aligned: fit g_W on the even windows from
  // v1 = v0 + g T + R0 beta, and evaluate on the odd ones (held out).
  Vec3 g_fit = Vec3::Zero();
  int fit_count = 0;
  for (size_t k = 0; k < windows.size(); k += 2) {
    const Window& w = windows[k];
    const ImuDelta d = w.pre.correctedDelta(w.s0.b_a, w.s0.b_g);
    g_fit += (w.s1.v_W - w.s0.v_W - w.s0.T_W_B.q * d.beta) / w.pre.sumDt();
    ++fit_count;
  }
  g_fit /= fit_count;
  const double tilt_deg = std::acos(-g_fit.z() / g_fit.norm()) * 180.0 / M_PI;

  std::vector<double> e_p, e_v, e_r, e_p_nominal_g, e_v_nominal_g, e_p_nobias, chi2;
  for (size_t k = 1; k < windows.size(); k += 2) {
    const Window& w = windows[k];
    const ImuState pred = w.pre.predict(w.s0, g_fit);
    const Vec3 dp = pred.T_W_B.p - w.s1.T_W_B.p;
    const Vec3 dv = pred.v_W - w.s1.v_W;
    const Vec3 dth = logSO3(w.s1.T_W_B.q.conjugate() * pred.T_W_B.q);
    e_p.push_back(dp.norm());
    e_v.push_back(dv.norm());
    e_r.push_back(dth.norm());
    // Errors normalised by the preintegration covariance (frame of body i); ground-truth errors not included.
    const Mat3 Rt = w.s0.T_W_B.R().transpose();
    Eigen::Matrix<double, 9, 1> e;
    e << Rt * dp, logSO3(w.pre.gamma().conjugate() * (w.s0.T_W_B.q.conjugate() * w.s1.T_W_B.q)), Rt * dv;
    chi2.push_back(e.dot(w.pre.covariance().topLeftCorner<9, 9>().ldlt().solve(e)));
    const ImuState nominal = w.pre.predict(w.s0);
    e_p_nominal_g.push_back((nominal.T_W_B.p - w.s1.T_W_B.p).norm());
    e_v_nominal_g.push_back((nominal.v_W - w.s1.v_W).norm());
    ImuState s0_nobias = w.s0;
    s0_nobias.b_a.setZero();
    s0_nobias.b_g.setZero();
    e_p_nobias.push_back((w.raw.predict(s0_nobias, g_fit).T_W_B.p - w.s1.T_W_B.p).norm());
  }
  const double mp = percentile(e_p, 0.5), mv = percentile(e_v, 0.5), mr = percentile(e_r, 0.5);
  std::printf("  EuRoC V1_01: fitted g_W = (%.4f, %.4f, %.4f) m/s^2, %.3f deg from -z, on %d windows\n",
              g_fit.x(), g_fit.y(), g_fit.z(), tilt_deg, fit_count);
  std::printf("  %zu held-out windows of 1 s, GT biases, fitted g_W:\n", e_p.size());
  std::printf("    position error median %.4f m, p90 %.4f m, max %.4f m\n", mp, percentile(e_p, 0.9),
              percentile(e_p, 1.0));
  std::printf("    velocity error median %.4f m/s, p90 %.4f m/s, max %.4f m/s\n", mv, percentile(e_v, 0.9),
              percentile(e_v, 1.0));
  std::printf("    rotation error median %.3f deg, p90 %.3f deg, max %.3f deg\n", mr * 180 / M_PI,
              percentile(e_r, 0.9) * 180 / M_PI, percentile(e_r, 1.0) * 180 / M_PI);
  std::printf("    chi2 (9 dof, IMU covariance only) median %.1f\n", percentile(chi2, 0.5));
  std::printf("    nominal g (0, 0, -9.81): position median %.4f m, velocity median %.4f m/s\n",
              percentile(e_p_nominal_g, 0.5), percentile(e_v_nominal_g, 0.5));
  std::printf("    zero biases: position median %.4f m\n", percentile(e_p_nobias, 0.5));
  EXPECT_LT(tilt_deg, 1.0);
  EXPECT_NEAR(g_fit.norm(), 9.81, 0.05);
  EXPECT_LT(mp, 0.015);
  EXPECT_LT(percentile(e_p, 0.9), 0.03);
  EXPECT_LT(mv, 0.03);
  EXPECT_LT(percentile(e_v, 0.9), 0.06);
  EXPECT_LT(mr, 0.3 * M_PI / 180);
  EXPECT_LT(percentile(e_r, 1.0), 1.0 * M_PI / 180);
  // The biases matter: without them the median error is several times larger.
  EXPECT_GT(percentile(e_p_nobias, 0.5), 3.0 * mp);
}

TEST(GravityAlignmentEuroc, RestAtTheStartIsStaticAndLevelledLikeTheGroundTruth) {
  const auto mav = testing::eurocMicroDir() / "mav0";
  LINNET_REQUIRE_SHARED_DATA(mav / "imu0" / "data.csv");
  LINNET_REQUIRE_SHARED_DATA(mav / "state_groundtruth_estimate0" / "data.csv");
  ImuBuffer buffer;
  for (const CsvRow& r : readCsv(mav / "imu0" / "data.csv", 7))
    buffer.append({r.t, Vec3(r.v[3], r.v[4], r.v[5]), Vec3(r.v[0], r.v[1], r.v[2])});
  const std::vector<CsvRow> gt = readCsv(mav / "state_groundtruth_estimate0" / "data.csv", 17);
  const StaticDetectionOptions opt;

  // First second: the MAV rests on the ground.
  const ImuState s0 = groundTruthState(gt[0]);
  const auto rest = buffer.samplesBetween(s0.t, s0.t + 1'000'000'000);
  const ImuStatistics raw = imuStatistics(rest);
  const ImuStatistics st = imuStatistics(rest, opt.averaging_samples);
  std::printf(
      "  EuRoC V1_01 first 1 s (rotors on): raw std acc %.3f m/s^2 gyr %.4f rad/s; block-mean std acc "
      "%.3f m/s^2 gyr %.4f rad/s; |acc mean| %.3f m/s^2\n",
      raw.acc_std.maxCoeff(), raw.gyr_std.maxCoeff(), st.acc_std.maxCoeff(), st.gyr_std.maxCoeff(),
      st.acc_mean.norm());
  EXPECT_TRUE(isStatic(rest, opt, 9.81));
  // The raw variances alone cannot tell this rest from flight.
  StaticDetectionOptions raw_opt = opt;
  raw_opt.averaging_samples = 1;
  EXPECT_FALSE(isStatic(rest, raw_opt, 9.81));
  // Gravity alignment with the ground-truth accelerometer bias removed: tilt vs the ground truth, whose world
  // frame is itself ~0.23 deg off gravity (see OneSecondWindowsMatchGroundTruth).
  const Quat q = gravityAlignedRotation(st.acc_mean - s0.b_a);
  const Vec3 z_est = q.conjugate() * Vec3::UnitZ(), z_gt = s0.T_W_B.q.conjugate() * Vec3::UnitZ();
  const double tilt_deg = std::acos(std::min(1.0, z_est.dot(z_gt))) * 180.0 / M_PI;
  std::printf("  gravity alignment at rest: tilt vs ground truth %.3f deg\n", tilt_deg);
  EXPECT_LT(tilt_deg, 0.5);
  EXPECT_NEAR(yawOf(q), 0.0, 1e-12);

  // In flight (the ground truth moves faster than 0.3 m/s): not static.
  int moving_windows = 0, flagged_static = 0;
  double min_gyr_std = 1e9;
  for (size_t i = 0; i + 20 < gt.size(); i += 40) {
    const ImuState s = groundTruthState(gt[i]);
    if (s.v_W.norm() < 0.3) continue;
    ++moving_windows;
    const auto window = buffer.samplesBetween(s.t, groundTruthState(gt[i + 20]).t);
    min_gyr_std = std::min(min_gyr_std, imuStatistics(window, opt.averaging_samples).gyr_std.maxCoeff());
    if (isStatic(window, opt, 9.81)) ++flagged_static;
  }
  std::printf(
      "  in flight: %d of %d one-second windows flagged static (smallest block-mean gyr std %.4f rad/s)\n",
      flagged_static, moving_windows, min_gyr_std);
  EXPECT_GT(moving_windows, 20);
  EXPECT_EQ(flagged_static, 0);
}

}  // namespace
}  // namespace linnet
