// Midpoint IMU preintegration with bias Jacobians and covariance. See preintegration.h for the model.
#include "linnet/imu/preintegration.h"

#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "linnet/core/error.h"
#include "linnet/core/options.h"
#include "linnet/core/pose.h"

namespace linnet {

Preintegration::Preintegration(const ImuNoise& noise, const Vec3& b_a, const Vec3& b_g,
                               const PreintegrationOptions& options)
    : noise_(noise), options_(options), b_a_(b_a), b_g_(b_g) {
  validateOptions(noise_, "imu");
  validateOptions(options_, "preintegration");
  if (!b_a_.allFinite() || !b_g_.allFinite())
    throw UsageError("Preintegration: non-finite linearisation bias");
}

Preintegration::Preintegration(const std::vector<ImuSample>& samples, const ImuNoise& noise, const Vec3& b_a,
                               const Vec3& b_g, const PreintegrationOptions& options)
    : Preintegration(noise, b_a, b_g, options) {
  samples_.reserve(samples.size());
  for (const ImuSample& s : samples) push(s);
}

void Preintegration::reset() {
  delta_ = ImuDelta();
  sum_dt_ = 0.0;
  jacobian_.setIdentity();
  covariance_.setZero();
  sqrt_info_valid_ = false;
}

const Mat15& Preintegration::sqrtInformation() const {
  if (!sqrt_info_valid_) {
    sqrt_info_ = sqrtInformationOf(covariance_);
    sqrt_info_valid_ = true;
  }
  return sqrt_info_;
}

Mat15 sqrtInformationOf(const Mat15& covariance) {
  if (!covariance.allFinite()) throw UsageError("ImuFactor: preintegration covariance is not finite");
  const Mat15 sym = 0.5 * (covariance + covariance.transpose());
  Eigen::SelfAdjointEigenSolver<Mat15> es(sym);
  const double lmax = es.eigenvalues().maxCoeff();
  if (!(lmax > 0.0))
    throw UsageError("ImuFactor: preintegration covariance is zero (empty interval or zero noise)");
  const Vec15 lambda = es.eigenvalues().cwiseMax(1e-14 * lmax);
  const Mat15 info = es.eigenvectors() * lambda.cwiseInverse().asDiagonal() * es.eigenvectors().transpose();
  const Eigen::LLT<Mat15> llt(0.5 * (info + info.transpose()));
  return llt.matrixU();  // info = U^T U
}

void Preintegration::push(const ImuSample& s) {
  if (!samples_.empty()) {
    const ImuSample& last = samples_.back();
    if (s.t < last.t)
      throw UsageError("Preintegration::push: IMU sample at t=" + std::to_string(s.t) +
                       " ns is earlier than the previous one at t=" + std::to_string(last.t) + " ns");
    if (s.t == last.t) return;
    integrateStep(last, s);
  }
  samples_.push_back(s);
}

void Preintegration::integrateStep(const ImuSample& s0, const ImuSample& s1) {
  const double dt = toSeconds(s1.t - s0.t);
  const double dt2 = dt * dt;

  const Vec3 a0 = s0.acc - b_a_;
  const Vec3 a1 = s1.acc - b_a_;
  const Vec3 w = 0.5 * (s0.gyr + s1.gyr) - b_g_;
  const Vec3 phi = w * dt;
  const Quat dq = expSO3(phi);
  const Mat3 dR = dq.toRotationMatrix();
  const Mat3 Jr = rightJacobianSO3(phi);

  const Mat3 R0 = delta_.gamma.toRotationMatrix();
  const Quat gamma1 = (delta_.gamma * dq).normalized();
  const Mat3 R1 = gamma1.toRotationMatrix();
  const Vec3 acc_mid = 0.5 * (R0 * a0 + R1 * a1);

  // Linearised error dynamics of one step (derivation: perturb gamma_k on the right, the biases additively,
  // then expand a and gamma_{k+1} to first order).
  const Mat3 A1 = R1 * skew(a1);
  const Mat3 dacc_dtheta = -0.5 * (R0 * skew(a0) + A1 * dR.transpose());  // d acc_mid / d theta_k
  const Mat3 dacc_dba = -0.5 * (R0 + R1);
  const Mat3 dacc_dbg = 0.5 * A1 * Jr * dt;

  Mat15 F = Mat15::Identity();
  F.block<3, 3>(kP, kR) = 0.5 * dt2 * dacc_dtheta;
  F.block<3, 3>(kP, kV) = Mat3::Identity() * dt;
  F.block<3, 3>(kP, kBa) = 0.5 * dt2 * dacc_dba;
  F.block<3, 3>(kP, kBg) = 0.5 * dt2 * dacc_dbg;
  F.block<3, 3>(kR, kR) = dR.transpose();
  F.block<3, 3>(kR, kBg) = -Jr * dt;
  F.block<3, 3>(kV, kR) = dt * dacc_dtheta;
  F.block<3, 3>(kV, kBa) = dt * dacc_dba;
  F.block<3, 3>(kV, kBg) = dt * dacc_dbg;

  // Noise n = [n_a0, n_g0, n_a1, n_g1, w_ba, w_bg] (18).
  Eigen::Matrix<double, 15, 18> G = Eigen::Matrix<double, 15, 18>::Zero();
  const Mat3 dtheta_dng = 0.5 * Jr * dt;  // per gyro end
  const Mat3 dacc_dna0 = 0.5 * R0;
  const Mat3 dacc_dna1 = 0.5 * R1;
  const Mat3 dacc_dng = -A1 * dtheta_dng * 0.5;  // through gamma_{k+1} in the second acceleration term
  G.block<3, 3>(kP, 0) = 0.5 * dt2 * dacc_dna0;
  G.block<3, 3>(kP, 3) = 0.5 * dt2 * dacc_dng;
  G.block<3, 3>(kP, 6) = 0.5 * dt2 * dacc_dna1;
  G.block<3, 3>(kP, 9) = 0.5 * dt2 * dacc_dng;
  G.block<3, 3>(kR, 3) = dtheta_dng;
  G.block<3, 3>(kR, 9) = dtheta_dng;
  G.block<3, 3>(kV, 0) = dt * dacc_dna0;
  G.block<3, 3>(kV, 3) = dt * dacc_dng;
  G.block<3, 3>(kV, 6) = dt * dacc_dna1;
  G.block<3, 3>(kV, 9) = dt * dacc_dng;
  G.block<3, 3>(kBa, 12) = Mat3::Identity();
  G.block<3, 3>(kBg, 15) = Mat3::Identity();

  double var_a = 2.0 * noise_.acc_noise_density * noise_.acc_noise_density / dt;
  double var_g = 2.0 * noise_.gyr_noise_density * noise_.gyr_noise_density / dt;
  if (options_.gap_dt_s > 0.0 && dt > options_.gap_dt_s) {
    // Each end's noise enters with weight dt / 2 (G above): 2 sigma^2 per end gives (sigma dt)^2 in velocity.
    var_a += 2.0 * options_.gap_acc_sigma * options_.gap_acc_sigma;
    var_g += 2.0 * options_.gap_gyr_sigma * options_.gap_gyr_sigma;
  }
  const double var_ba = noise_.acc_random_walk * noise_.acc_random_walk * dt;
  const double var_bg = noise_.gyr_random_walk * noise_.gyr_random_walk * dt;
  Eigen::Matrix<double, 18, 1> q;
  q << Vec3::Constant(var_a), Vec3::Constant(var_g), Vec3::Constant(var_a), Vec3::Constant(var_g),
      Vec3::Constant(var_ba), Vec3::Constant(var_bg);

  covariance_ = F * covariance_ * F.transpose() + G * q.asDiagonal() * G.transpose();
  covariance_.block<3, 3>(kP, kP).diagonal().array() +=
      options_.integration_noise * options_.integration_noise * dt;
  covariance_ = 0.5 * (covariance_ + covariance_.transpose()).eval();
  sqrt_info_valid_ = false;
  jacobian_ = F * jacobian_;

  delta_.alpha += delta_.beta * dt + 0.5 * acc_mid * dt2;
  delta_.beta += acc_mid * dt;
  delta_.gamma = gamma1;
  sum_dt_ += dt;
}

void Preintegration::repropagate(const Vec3& b_a, const Vec3& b_g) {
  b_a_ = b_a;
  b_g_ = b_g;
  reset();
  for (size_t k = 1; k < samples_.size(); ++k) integrateStep(samples_[k - 1], samples_[k]);
}

void Preintegration::append(const Preintegration& next) {
  if (next.samples_.empty()) return;
  if (samples_.empty()) {
    for (const ImuSample& s : next.samples_) push(s);
    return;
  }
  if (next.startTime() != endTime())
    throw UsageError(
        "Preintegration::append: the next preintegration starts at t=" + std::to_string(next.startTime()) +
        " ns, this one ends at t=" + std::to_string(endTime()) + " ns");
  samples_.reserve(samples_.size() + next.samples_.size() - 1);
  for (size_t k = 1; k < next.samples_.size(); ++k) push(next.samples_[k]);
}

ImuDelta Preintegration::correctedDelta(const Vec3& b_a, const Vec3& b_g) const {
  const Vec3 dba = b_a - b_a_;
  const Vec3 dbg = b_g - b_g_;
  ImuDelta d;
  d.alpha = delta_.alpha + jacobian_.block<3, 3>(kP, kBa) * dba + jacobian_.block<3, 3>(kP, kBg) * dbg;
  d.beta = delta_.beta + jacobian_.block<3, 3>(kV, kBa) * dba + jacobian_.block<3, 3>(kV, kBg) * dbg;
  d.gamma = (delta_.gamma * expSO3(jacobian_.block<3, 3>(kR, kBg) * dbg)).normalized();
  return d;
}

bool Preintegration::biasMovedFar(const Vec3& b_a, const Vec3& b_g) const {
  return (b_a - b_a_).norm() > options_.max_acc_bias_change ||
         (b_g - b_g_).norm() > options_.max_gyr_bias_change;
}

ImuState Preintegration::predict(const ImuState& state_i) const {
  return predict(state_i, noise_.gravityVector());
}

ImuState Preintegration::predict(const ImuState& state_i, const Vec3& g) const {
  const ImuDelta d = correctedDelta(state_i.b_a, state_i.b_g);
  const double T = sum_dt_;
  const Quat& q_i = state_i.T_W_B.q;
  ImuState s = state_i;
  s.t = state_i.t + (endTime() - startTime());
  s.T_W_B = Pose(q_i * d.gamma, state_i.T_W_B.p + state_i.v_W * T + 0.5 * g * T * T + q_i * d.alpha);
  s.v_W = state_i.v_W + g * T + q_i * d.beta;
  return s;
}

}  // namespace linnet
