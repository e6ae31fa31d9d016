// IMU preintegration between two frames i and j (midpoint rule), with first-order bias correction and
// covariance.
//
// Following VINS-Mono (Qin et al., T-RO 2018) and Forster et al., "On-Manifold Preintegration for Real-Time
// Visual-Inertial Odometry" (T-RO 2017). With biases b_a, b_g held at the linearisation point, the deltas in
// the body frame at i are
//   gamma_{k+1} = gamma_k Exp(w dt),               w = (w_k + w_{k+1}) / 2 - b_g
//   a           = (gamma_k (a_k - b_a) + gamma_{k+1} (a_{k+1} - b_a)) / 2
//   alpha_{k+1} = alpha_k + beta_k dt + a dt^2 / 2  (position)
//   beta_{k+1}  = beta_k + a dt                      (velocity)
// so that   p_j = p_i + v_i T + g_W T^2 / 2 + R_i alpha,   v_j = v_i + g_W T + R_i beta,   q_j = q_i gamma.
//
// Error state (15), in this order everywhere (also the IMU factor's residual order):
//   [0,3) d_alpha  [3,6) d_theta (right perturbation: gamma_true = gamma Exp(d_theta))  [6,9) d_beta
//   [9,12) d_b_a   [12,15) d_b_g
// jacobian() is d(deltas)/d(biases at i) accumulated as J <- F J; covariance() is P <- F P F^T + G Q G^T,
// with the exact discrete transition F of one midpoint step (equivalent to I + F_c dt to first order).
//
// Noise (ImuNoise: continuous densities sigma): the midpoint average of two readings is treated as one
// reading of the continuous white noise, so each end is given variance 2 sigma^2 / dt (the average then has
// sigma^2 / dt, which integrates to the continuous-time sigma^2 T over the interval; checked against Monte
// Carlo in test_preintegration.cc); bias random walks add sigma_b^2 dt per step, and
// PreintegrationOptions::integration_noise adds a small position random walk.
//
// The raw samples are kept: repropagate() re-integrates them at new linearisation biases and append() merges
// the next preintegration (which must start where this one ends) when a non-keyframe is dropped.
#pragma once

#include <vector>

#include "linnet/core/types.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

struct PreintegrationOptions {
  double max_acc_bias_change = 0.25;  // m/s^2: biasMovedFar() when |b_a - b_a_lin| exceeds this
  double max_gyr_bias_change = 0.02;  // rad/s: biasMovedFar() when |b_g - b_g_lin| exceeds this
  // m/sqrt(s): position random walk added per step (variance sigma^2 dt) for integration / model error, as
  // GTSAM's integrationCovariance. Without it, alpha and beta of a one- or two-step preintegration are almost
  // perfectly correlated and the IMU factor's information reaches ~1e20 in that direction.
  double integration_noise = 1e-5;
  // A step longer than gap_dt_s (0: never) is a gap in the samples: the motion in between is unknown, so the step
  // gets an extra acceleration / angular-rate noise of gap_acc_sigma (m/s^2) / gap_gyr_sigma (rad/s), constant over
  // the step (velocity variance += (gap_acc_sigma dt)^2, rotation variance += (gap_gyr_sigma dt)^2).
  double gap_dt_s = 0.0;
  double gap_acc_sigma = 0.0;
  double gap_gyr_sigma = 0.0;

  template <class V>
  void visit(V& v) {
    v("integration_noise", integration_noise, "position random walk for integration error, m/sqrt(s)", 0.0,
      1.0);
    v("gap_dt_s", gap_dt_s, "a step longer than this is a gap with extra noise (0: never), s", 0.0, 100.0);
    v("gap_acc_sigma", gap_acc_sigma, "unknown acceleration over a gap step, m/s^2", 0.0, 100.0);
    v("gap_gyr_sigma", gap_gyr_sigma, "unknown angular rate over a gap step, rad/s", 0.0, 100.0);
    v("max_acc_bias_change", max_acc_bias_change,
      "accelerometer bias change that triggers repropagation, m/s^2", 0.0, 10.0);
    v("max_gyr_bias_change", max_gyr_bias_change, "gyroscope bias change that triggers repropagation, rad/s",
      0.0, 1.0);
  }
};

/// Preintegrated deltas (in the body frame at i) for given biases.
struct ImuDelta {
  Vec3 alpha = Vec3::Zero();      // position delta, m
  Vec3 beta = Vec3::Zero();       // velocity delta, m/s
  Quat gamma = Quat::Identity();  // rotation R_Bi_Bj
};

class Preintegration {
 public:
  // Offsets of the error-state / residual blocks.
  static constexpr int kP = 0, kR = 3, kV = 6, kBa = 9, kBg = 12;

  /// Empty preintegration linearised at biases (b_a, b_g). Push the sample at t_i first (see ImuBuffer).
  /// Throws ConfigError naming the key ("imu.<field>" / "preintegration.<field>") if an option is out of
  /// range.
  Preintegration(const ImuNoise& noise, const Vec3& b_a, const Vec3& b_g,
                 const PreintegrationOptions& options = PreintegrationOptions());
  /// Convenience: integrates `samples` (the first one at t_i, the last one at t_j).
  Preintegration(const std::vector<ImuSample>& samples, const ImuNoise& noise, const Vec3& b_a,
                 const Vec3& b_g, const PreintegrationOptions& options = PreintegrationOptions());

  /// Adds one sample. The first sample only sets the start time. A sample at the same time as the previous
  /// one is ignored; an earlier one throws UsageError (naming both time stamps).
  void push(const ImuSample& s);

  /// Re-integrates all samples with new linearisation biases.
  void repropagate(const Vec3& b_a, const Vec3& b_g);

  /// Appends `next` (which must start at this one's end time, else UsageError): afterwards this covers both
  /// intervals, integrated at this one's linearisation biases.
  void append(const Preintegration& next);

  /// Deltas corrected to first order for biases (b_a, b_g):
  /// alpha + J_alpha_ba dba + J_alpha_bg dbg, beta + ..., gamma Exp(J_theta_bg dbg).
  ImuDelta correctedDelta(const Vec3& b_a, const Vec3& b_g) const;

  /// True when (b_a, b_g) is far enough from the linearisation point that first-order correction is poor.
  bool biasMovedFar(const Vec3& b_a, const Vec3& b_g) const;

  /// State at the end time from the state at the start time (biases of state_i used and kept), gravity from
  /// noise().
  ImuState predict(const ImuState& state_i) const;
  /// The same with an explicit gravity vector in W (e.g. a refined gravity direction).
  ImuState predict(const ImuState& state_i, const Vec3& g_W) const;

  // Accessors.
  double sumDt() const { return sum_dt_; }  // s, end time - start time
  Timestamp startTime() const { return samples_.empty() ? 0 : samples_.front().t; }
  Timestamp endTime() const { return samples_.empty() ? 0 : samples_.back().t; }
  bool empty() const { return samples_.size() < 2; }  // nothing integrated yet
  const std::vector<ImuSample>& samples() const { return samples_; }
  const ImuDelta& delta() const { return delta_; }  // at the linearisation biases
  const Vec3& alpha() const { return delta_.alpha; }
  const Vec3& beta() const { return delta_.beta; }
  const Quat& gamma() const { return delta_.gamma; }
  const Mat15& jacobian() const { return jacobian_; }
  const Mat15& covariance() const { return covariance_; }
  /// sqrtInformationOf(covariance()), computed once per covariance (the window's solves build a factor from each
  /// preintegration every frame; the 15 x 15 eigen-decomposition was most of that).
  const Mat15& sqrtInformation() const;
  const Vec3& linearisedBa() const { return b_a_; }
  const Vec3& linearisedBg() const { return b_g_; }
  const ImuNoise& noise() const { return noise_; }
  const PreintegrationOptions& options() const { return options_; }

 private:
  void reset();
  void integrateStep(const ImuSample& s0, const ImuSample& s1);

  ImuNoise noise_;
  PreintegrationOptions options_;
  Vec3 b_a_ = Vec3::Zero(), b_g_ = Vec3::Zero();  // linearisation point
  std::vector<ImuSample> samples_;
  ImuDelta delta_;
  double sum_dt_ = 0.0;
  Mat15 jacobian_ = Mat15::Identity();
  Mat15 covariance_ = Mat15::Zero();
  mutable Mat15 sqrt_info_;                // cache of sqrtInformation()
  mutable bool sqrt_info_valid_ = false;  // reset whenever the covariance changes
};

/// Upper-triangular S with S^T S = covariance^-1 (eigenvalues below 1e-14 of the largest are floored there).
/// Throws UsageError if the covariance is not finite or is zero.
Mat15 sqrtInformationOf(const Mat15& covariance);

}  // namespace linnet
