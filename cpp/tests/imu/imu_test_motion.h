// A smooth analytic body motion with exact IMU readings, for preintegration and IMU-factor tests.
//   p_W(t) = sinusoids, R_W_B(t) = R0 Exp(theta(t)) with theta(t) sinusoidal + a slow yaw ramp.
//   omega_B = Jr(theta) theta',  f_B = R^T (a_W - g_W).
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/imu/imu_types.h"

namespace linnet::testing {

struct SmoothMotion {
  Vec3 amp = Vec3(1.0, 0.8, 0.3);       // m
  Vec3 freq = Vec3(0.7, 0.5, 0.9);      // rad/s
  Vec3 rot_amp = Vec3(0.3, 0.2, 0.0);   // rad
  Vec3 rot_freq = Vec3(0.8, 1.1, 0.0);  // rad/s
  double yaw_rate = 0.4;                // rad/s
  Vec3 p0 = Vec3(0.5, -1.0, 1.2);
  Quat R0 = Quat(Eigen::AngleAxisd(0.3, Vec3(0.2, 0.3, 1.0).normalized()));
  double gravity = 9.81;

  Vec3 theta(double t) const {
    Vec3 th;
    for (int k = 0; k < 3; ++k) th[k] = rot_amp[k] * std::sin(rot_freq[k] * t);
    th.z() += yaw_rate * t;
    return th;
  }
  Vec3 thetaDot(double t) const {
    Vec3 d;
    for (int k = 0; k < 3; ++k) d[k] = rot_amp[k] * rot_freq[k] * std::cos(rot_freq[k] * t);
    d.z() += yaw_rate;
    return d;
  }
  Vec3 position(double t) const {
    return p0 + Vec3(amp.x() * std::sin(freq.x() * t), amp.y() * std::cos(freq.y() * t),
                     amp.z() * std::sin(freq.z() * t));
  }
  Vec3 velocity(double t) const {
    return Vec3(amp.x() * freq.x() * std::cos(freq.x() * t), -amp.y() * freq.y() * std::sin(freq.y() * t),
                amp.z() * freq.z() * std::cos(freq.z() * t));
  }
  Vec3 acceleration(double t) const {
    return Vec3(-amp.x() * freq.x() * freq.x() * std::sin(freq.x() * t),
                -amp.y() * freq.y() * freq.y() * std::cos(freq.y() * t),
                -amp.z() * freq.z() * freq.z() * std::sin(freq.z() * t));
  }
  Quat rotation(double t) const { return (R0 * expSO3(theta(t))).normalized(); }

  ImuState state(Timestamp t_ns, const Vec3& b_a = Vec3::Zero(), const Vec3& b_g = Vec3::Zero()) const {
    const double t = toSeconds(t_ns);
    ImuState s;
    s.t = t_ns;
    s.T_W_B = Pose(rotation(t), position(t));
    s.v_W = velocity(t);
    s.b_a = b_a;
    s.b_g = b_g;
    return s;
  }

  /// Exact reading (plus constant biases) at time t.
  ImuSample sample(Timestamp t_ns, const Vec3& b_a = Vec3::Zero(), const Vec3& b_g = Vec3::Zero()) const {
    const double t = toSeconds(t_ns);
    ImuSample s;
    s.t = t_ns;
    s.gyr = rightJacobianSO3(theta(t)) * thetaDot(t) + b_g;
    const Vec3 g_W(0.0, 0.0, -gravity);
    s.acc = rotation(t).conjugate() * (acceleration(t) - g_W) + b_a;
    return s;
  }

  /// Readings from t0 to t1 inclusive every dt (t1 - t0 must be a multiple of dt).
  std::vector<ImuSample> samples(Timestamp t0, Timestamp t1, Timestamp dt, const Vec3& b_a = Vec3::Zero(),
                                 const Vec3& b_g = Vec3::Zero()) const {
    std::vector<ImuSample> out;
    for (Timestamp t = t0; t <= t1; t += dt) out.push_back(sample(t, b_a, b_g));
    return out;
  }
};

/// Adds white noise with continuous densities (noise.*_noise_density) to readings taken every dt seconds.
inline std::vector<ImuSample> addWhiteNoise(std::vector<ImuSample> samples, const ImuNoise& noise, double dt,
                                            std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const double sa = noise.acc_noise_density / std::sqrt(dt);
  const double sg = noise.gyr_noise_density / std::sqrt(dt);
  for (ImuSample& s : samples) {
    for (int k = 0; k < 3; ++k) s.acc[k] += sa * n(rng);
    for (int k = 0; k < 3; ++k) s.gyr[k] += sg * n(rng);
  }
  return samples;
}

}  // namespace linnet::testing
