// A synthetic stereo-inertial world for estimator tests (no images): a smooth analytic trajectory, IMU at 200 Hz
// derived from it exactly (specific force = R^T (a - g)), random 3D points in a shell around the path, and
// FrameObservations at 20 Hz with stereo projections through EuRoC's extrinsics.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/imu/imu_types.h"

namespace linnet::testing {

/// EuRoC's camera extrinsics (V1_01_easy mav0/cam0, cam1 sensor.yaml T_BS).
inline Pose eurocTBC0() {
  Mat4 T;
  T << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975, 0.999557249008, 0.0149672133247,
      0.025715529948, -0.064676986768, -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949, 0, 0, 0,
      1;
  return Pose::fromMatrix(T);
}
inline Pose eurocTBC1() {
  Mat4 T;
  T << 0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556, 0.999598781151, 0.0130119051815,
      0.0251588363115, 0.0453689425024, -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038, 0, 0,
      0, 1;
  return Pose::fromMatrix(T);
}

struct SyntheticOptions {
  double duration_s = 20.0;       // length of the frame sequence, s
  double imu_lead_s = 1.0;        // IMU before the first frame, s
  double static_s = 0.0;          // at rest this long from the start of the IMU, then a 2 s C2 ramp into motion
  double pos_amp = 1.0;           // position sinusoid amplitude, m
  double att_amp = 0.15;          // attitude oscillation amplitude, rad
  bool imu_noise = false;         // white noise at the densities below (the biases are always applied)
  double acc_noise = 2.0e-3;      // m/s^2/sqrt(Hz) (EuRoC ADIS16448)
  double gyr_noise = 1.6968e-4;   // rad/s/sqrt(Hz)
  Vec3 acc_bias = Vec3(0.03, -0.02, 0.04);   // m/s^2
  Vec3 gyr_bias = Vec3(0.002, -0.003, 0.001);  // rad/s
  double pixel_noise = 0.3;       // std, pixels
  int num_points = 1500;
  double focal = 458.0;           // pixels
  bool stereo = true;
  std::uint64_t seed = 7;
  double camera_time_offset_s = 0.0;  // frame stamps are the capture time plus this (camera-to-IMU offset), s
  Pose calibration_error;             // the extrinsics handed to the estimator are calibration_error * T_B_Ci
  Pose stereo_error;                  // ... and cam1's is calibration_error * T_B_C1 * stereo_error
};

/// Ground truth of one instant.
struct TruthState {
  Pose T_W_B;
  Vec3 v_W, a_W, omega_B;
};

class SyntheticVio {
 public:
  explicit SyntheticVio(const SyntheticOptions& o) : o_(o), rng_(o.seed) {
    // Body x up, body z (camera optical axis) along world +x: EuRoC's mounting.
    Mat3 R0;
    R0.col(0) = Vec3(0, 0, 1);
    R0.col(1) = Vec3(0, -1, 0);
    R0.col(2) = Vec3(1, 0, 0);
    R0_ = Quat(R0);
    std::uniform_real_distribution<double> u(-1.0, 1.0), r(5.0, 9.0);
    for (int i = 0; i < o_.num_points; ++i) {
      Vec3 d(u(rng_), u(rng_), 0.6 * u(rng_));
      if (d.norm() < 1e-3) d = Vec3(1, 0, 0);
      points_.push_back(d.normalized() * r(rng_));
    }
    track_.assign(points_.size(), 0);
    const Timestamp t_end = fromSeconds(o_.imu_lead_s + o_.duration_s);
    const double sa = o_.acc_noise * std::sqrt(200.0), sg = o_.gyr_noise * std::sqrt(200.0);
    std::normal_distribution<double> n(0.0, 1.0);
    for (Timestamp t = 0; t <= t_end + fromSeconds(0.05); t += 5'000'000) {
      const TruthState s = truth(t);
      ImuSample m;
      m.t = t;
      m.acc = s.T_W_B.R().transpose() * (s.a_W - Vec3(0, 0, -9.81)) + o_.acc_bias;
      m.gyr = s.omega_B + o_.gyr_bias;
      if (o_.imu_noise) {
        m.acc += sa * Vec3(n(rng_), n(rng_), n(rng_));
        m.gyr += sg * Vec3(n(rng_), n(rng_), n(rng_));
      }
      imu_.push_back(m);
    }
    // Frames are captured at t; their stamps carry the camera time offset.
    for (Timestamp t = fromSeconds(o_.imu_lead_s); t <= t_end; t += 50'000'000) frames_.push_back(observe(t));
  }

  const std::vector<ImuSample>& imu() const { return imu_; }
  const std::vector<FrameObservations>& frames() const { return frames_; }
  const std::vector<Vec3>& points() const { return points_; }
  const SyntheticOptions& options() const { return o_; }

  /// Analytic ground truth at time t (ns).
  TruthState truth(Timestamp t) const {
    const double s = toSeconds(t);
    double e, de, dde;
    envelope(s, &e, &de, &dde);
    const double w[3] = {0.9, 0.7, 1.1}, ph[3] = {0.0, 1.0, 2.0};
    Vec3 f, df, ddf, g, dg, ddg;
    for (int k = 0; k < 3; ++k) {
      const double arg = w[k] * s + ph[k];
      f[k] = o_.pos_amp * (k == 2 ? 0.4 : 1.0) * (std::sin(arg) - std::sin(ph[k]));
      df[k] = o_.pos_amp * (k == 2 ? 0.4 : 1.0) * w[k] * std::cos(arg);
      ddf[k] = -o_.pos_amp * (k == 2 ? 0.4 : 1.0) * w[k] * w[k] * std::sin(arg);
      const double wa = 1.3 * w[k];
      g[k] = o_.att_amp * std::sin(wa * s + ph[k]);
      dg[k] = o_.att_amp * wa * std::cos(wa * s + ph[k]);
      ddg[k] = -o_.att_amp * wa * wa * std::sin(wa * s + ph[k]);
    }
    (void)ddg;
    TruthState out;
    const Vec3 p = e * f, v = de * f + e * df, a = dde * f + 2.0 * de * df + e * ddf;
    const Vec3 theta = e * g, dtheta = de * g + e * dg;
    out.T_W_B = Pose(R0_ * expSO3(theta), p);
    out.v_W = v;
    out.a_W = a;
    out.omega_B = rightJacobianSO3(theta) * dtheta;  // R = R0 Exp(theta): omega_B = Jr(theta) dtheta/dt
    return out;
  }

 private:
  // C2 ramp from 0 (before static_s) to 1 (after static_s + 2 s): quintic smoothstep.
  void envelope(double s, double* e, double* de, double* dde) const {
    if (o_.static_s <= 0.0) {
      *e = 1.0, *de = 0.0, *dde = 0.0;
      return;
    }
    const double T = 2.0, x = (s - o_.static_s) / T;
    if (x <= 0.0) {
      *e = *de = *dde = 0.0;
    } else if (x >= 1.0) {
      *e = 1.0, *de = 0.0, *dde = 0.0;
    } else {
      *e = x * x * x * (10.0 - 15.0 * x + 6.0 * x * x);
      *de = 30.0 * x * x * (1.0 - x) * (1.0 - x) / T;
      *dde = 60.0 * x * (1.0 - x) * (1.0 - 2.0 * x) / (T * T);
    }
  }

  FrameObservations observe(Timestamp t) {
    FrameObservations obs;
    obs.t = t + fromSeconds(o_.camera_time_offset_s);
    obs.stereo = o_.stereo;
    const Pose T_W_B = truth(t).T_W_B;
    const Pose T_C0_W = (T_W_B * eurocTBC0()).inverse(), T_C1_W = (T_W_B * eurocTBC1()).inverse();
    std::normal_distribution<double> n(0.0, o_.pixel_noise / o_.focal);
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const Vec3 c0 = T_C0_W * points_[i], c1 = T_C1_W * points_[i];
      Vec2 uv0;
      if (!visible(c0, &uv0)) {
        track_[i] = 0;
        continue;
      }
      PointObservation p;
      p.id = static_cast<std::int64_t>(i);
      p.uv0 = uv0 + Vec2(n(rng_), n(rng_));
      p.px0 = Vec2(o_.focal * p.uv0.x() + 376.0, o_.focal * p.uv0.y() + 240.0);
      Vec2 uv1;
      if (o_.stereo && visible(c1, &uv1)) {
        p.has_right = true;
        p.uv1 = uv1 + Vec2(n(rng_), n(rng_));
        p.px1 = Vec2(o_.focal * p.uv1.x() + 376.0, o_.focal * p.uv1.y() + 240.0);
      }
      p.track_length = ++track_[i];
      obs.points.push_back(p);
    }
    return obs;
  }

  bool visible(const Vec3& c, Vec2* uv) const {
    if (c.z() < 0.3) return false;
    *uv = Vec2(c.x() / c.z(), c.y() / c.z());
    return std::abs(o_.focal * uv->x()) < 360.0 && std::abs(o_.focal * uv->y()) < 230.0;
  }


  SyntheticOptions o_;
  std::mt19937_64 rng_;
  Quat R0_;
  std::vector<Vec3> points_;
  std::vector<ImuSample> imu_;
  std::vector<FrameObservations> frames_;
  std::vector<int> track_;
};

}  // namespace linnet::testing
