// Preintegration: closed-form motions, prediction, bias-correction Jacobians, covariance, merge,
// repropagation.
#include <cmath>
#include <cstdio>
#include <random>

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "imu/imu_test_motion.h"
#include "linnet/core/error.h"
#include "linnet/imu/preintegration.h"

namespace linnet {
namespace {

constexpr Timestamp kMs = 1'000'000;  // ns

// Closed form for constant body rate w and constant specific force a (zero biases):
//   gamma(t) = Exp(w t),  beta(t) = [int_0^t Exp(w s) ds] a,  alpha(t) = [int_0^t int_0^s Exp(w u) du ds] a
// with Exp(w s) = I + sin(|w| s) K + (1 - cos(|w| s)) K^2, K = [w/|w|]x (Rodrigues).
void closedForm(const Vec3& w, const Vec3& a, double t, Vec3* alpha, Vec3* beta, Quat* gamma) {
  const double n = w.norm();
  const Mat3 K = skew(w / n);
  const double th = n * t;
  const Mat3 int1 = t * Mat3::Identity() + (1.0 - std::cos(th)) / n * K + (t - std::sin(th) / n) * K * K;
  const Mat3 int2 = 0.5 * t * t * Mat3::Identity() + (t - std::sin(th) / n) / n * K +
                    (0.5 * t * t - (1.0 - std::cos(th)) / (n * n)) * K * K;
  *beta = int1 * a;
  *alpha = int2 * a;
  *gamma = expSO3(w * t);
}

std::vector<ImuSample> constantSamples(const Vec3& acc, const Vec3& gyr, Timestamp t0, Timestamp t1,
                                       Timestamp dt) {
  std::vector<ImuSample> out;
  for (Timestamp t = t0; t <= t1; t += dt) out.push_back({t, acc, gyr});
  return out;
}

TEST(Preintegration, ConstantRateAndBodyAccelerationMatchClosedForm) {
  const Vec3 w(0.3, -0.5, 0.8), a(1.0, -0.4, 2.0);
  const ImuNoise noise;
  for (Timestamp dt : {5 * kMs, 1 * kMs}) {
    const Preintegration pre(constantSamples(a, w, 0, 1000 * kMs, dt), noise, Vec3::Zero(), Vec3::Zero());
    Vec3 alpha, beta;
    Quat gamma;
    closedForm(w, a, 1.0, &alpha, &beta, &gamma);
    EXPECT_DOUBLE_EQ(pre.sumDt(), 1.0);
    EXPECT_LT(pre.gamma().angularDistance(gamma), 1e-12);  // exact: constant rate, exact Exp
    // The midpoint (trapezoidal) rule on the rotated acceleration: error O(dt^2).
    const double h = toSeconds(dt);
    std::printf("  closed form, dt %.4f s: |d alpha| %.3g m, |d beta| %.3g m/s, gamma %.3g rad\n", h,
                (pre.alpha() - alpha).norm(), (pre.beta() - beta).norm(), pre.gamma().angularDistance(gamma));
    EXPECT_LT((pre.beta() - beta).norm(), 0.2 * h * h * a.norm()) << "dt " << h;
    EXPECT_LT((pre.alpha() - alpha).norm(), 0.2 * h * h * a.norm()) << "dt " << h;
  }
}

TEST(Preintegration, RestWithGravityPredictsNoMotion) {
  const ImuNoise noise;
  const Quat q_W_B(Eigen::AngleAxisd(0.4, Vec3(1.0, -2.0, 0.5).normalized()));
  const Vec3 f_B = q_W_B.conjugate() * Vec3(0.0, 0.0, noise.gravity);  // specific force at rest
  const Vec3 b_a(0.05, -0.02, 0.1), b_g(0.01, 0.002, -0.004);
  const Preintegration pre(constantSamples(f_B + b_a, b_g, 0, 2000 * kMs, 5 * kMs), noise, b_a, b_g);
  ImuState s0;
  s0.T_W_B = Pose(q_W_B, Vec3(1.0, 2.0, 3.0));
  s0.b_a = b_a;
  s0.b_g = b_g;
  const ImuState s1 = pre.predict(s0);
  EXPECT_EQ(s1.t, s0.t + 2000 * kMs);
  EXPECT_LT((s1.T_W_B.p - s0.T_W_B.p).norm(), 1e-12);
  EXPECT_LT(s1.v_W.norm(), 1e-12);
  EXPECT_LT(s1.T_W_B.q.angularDistance(q_W_B), 1e-12);
  EXPECT_EQ(s1.b_a, b_a);
}

TEST(Preintegration, PredictFollowsSmoothMotionWithSecondOrderAccuracy) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  double previous_error = 0.0;
  for (Timestamp dt : {10 * kMs, 5 * kMs, kMs * 5 / 2}) {
    const Timestamp t0 = 300 * kMs, t1 = 1300 * kMs;
    const Preintegration pre(m.samples(t0, t1, dt), noise, Vec3::Zero(), Vec3::Zero());
    const ImuState truth = m.state(t1);
    const ImuState pred = pre.predict(m.state(t0));
    const double ep = (pred.T_W_B.p - truth.T_W_B.p).norm();
    const double ev = (pred.v_W - truth.v_W).norm();
    const double er = pred.T_W_B.q.angularDistance(truth.T_W_B.q);
    std::printf("  smooth motion 1 s, dt %.4f s: position %.3g m, velocity %.3g m/s, rotation %.3g rad\n",
                toSeconds(dt), ep, ev, er);
    EXPECT_LT(ep, 2e-4);
    EXPECT_LT(ev, 5e-4);
    EXPECT_LT(er, 1e-4);
    if (previous_error > 0.0) {
      EXPECT_LT(ev, 0.35 * previous_error) << "halving dt should quarter the error";
    }
    previous_error = ev;
  }
}

TEST(Preintegration, BiasJacobiansMatchRepropagation) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  const Vec3 b_a0(0.1, -0.05, 0.2), b_g0(0.01, -0.02, 0.005);
  const auto samples = m.samples(0, 1000 * kMs, 5 * kMs, b_a0, b_g0);
  const Preintegration pre(samples, noise, b_a0, b_g0);

  // Column by column against central differences of full repropagations.
  const double h = 1e-6;
  for (int c = 0; c < 6; ++c) {
    Vec3 dba = Vec3::Zero(), dbg = Vec3::Zero();
    (c < 3 ? dba : dbg)[c % 3] = h;
    Preintegration plus = pre, minus = pre;
    plus.repropagate(b_a0 + dba, b_g0 + dbg);
    minus.repropagate(b_a0 - dba, b_g0 - dbg);
    const int col = (c < 3 ? Preintegration::kBa : Preintegration::kBg) + c % 3;
    const Vec3 d_alpha = (plus.alpha() - minus.alpha()) / (2 * h);
    const Vec3 d_beta = (plus.beta() - minus.beta()) / (2 * h);
    const Vec3 d_theta = logSO3(minus.gamma().conjugate() * plus.gamma()) / (2 * h);
    EXPECT_LT((pre.jacobian().block<3, 1>(Preintegration::kP, col) - d_alpha).norm(),
              1e-5 * (1 + d_alpha.norm()));
    EXPECT_LT((pre.jacobian().block<3, 1>(Preintegration::kV, col) - d_beta).norm(),
              1e-5 * (1 + d_beta.norm()));
    // dgamma/dbg is evaluated at the linearisation point: compare in the tangent of gamma.
    EXPECT_LT((pre.jacobian().block<3, 1>(Preintegration::kR, col) - d_theta).norm(),
              1e-5 * (1 + d_theta.norm()));
  }

  // First-order correction: the residual error shrinks quadratically with the bias change.
  double previous = 0.0;
  for (double scale : {0.04, 0.02, 0.01}) {
    const Vec3 dba = scale * Vec3(1.0, -2.0, 0.5), dbg = 0.1 * scale * Vec3(-0.5, 1.0, 2.0);
    Preintegration re = pre;
    re.repropagate(b_a0 + dba, b_g0 + dbg);
    const ImuDelta corr = pre.correctedDelta(b_a0 + dba, b_g0 + dbg);
    const double err = (corr.alpha - re.alpha()).norm() + (corr.beta - re.beta()).norm() +
                       corr.gamma.angularDistance(re.gamma());
    const double change = (pre.alpha() - re.alpha()).norm() + (pre.beta() - re.beta()).norm();
    std::printf("  bias change x%.2f: first-order correction error %.3g (delta change %.3g)\n", scale, err,
                change);
    EXPECT_LT(err, 0.05 * change);
    if (previous > 0.0) {
      EXPECT_LT(err, 0.3 * previous);
    }
    previous = err;
  }
}

TEST(Preintegration, CovarianceIsSymmetricPositiveDefiniteAndGrows) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  Preintegration pre(noise, Vec3::Zero(), Vec3::Zero());
  double previous_trace = 0.0;
  for (Timestamp t = 0; t <= 1000 * kMs; t += 5 * kMs) {
    pre.push(m.sample(t));
    if (t % (200 * kMs) != 0 || t == 0) continue;
    const Mat15& P = pre.covariance();
    EXPECT_LT((P - P.transpose()).norm(), 1e-15 * P.norm());
    const Eigen::SelfAdjointEigenSolver<Mat15> es(P);
    EXPECT_GT(es.eigenvalues().minCoeff(), 0.0);
    EXPECT_EQ(Eigen::LLT<Mat15>(P).info(), Eigen::Success);
    EXPECT_GT(P.trace(), previous_trace);
    previous_trace = P.trace();
  }
  // Bias blocks are pure random walks: sigma_b^2 T.
  const double T = pre.sumDt();
  EXPECT_NEAR(pre.covariance()(Preintegration::kBa, Preintegration::kBa),
              noise.acc_random_walk * noise.acc_random_walk * T, 1e-15);
  EXPECT_NEAR(pre.covariance()(Preintegration::kBg, Preintegration::kBg),
              noise.gyr_random_walk * noise.gyr_random_walk * T, 1e-18);
}

TEST(Preintegration, CovarianceMatchesMonteCarlo) {
  // White noise only (no bias walk): the propagated 9x9 [alpha, theta, beta] covariance vs sample covariance.
  const testing::SmoothMotion m;
  ImuNoise noise;
  noise.acc_noise_density = 0.02;
  noise.gyr_noise_density = 0.002;
  noise.acc_random_walk = 0.0;
  noise.gyr_random_walk = 0.0;
  const Timestamp dt = 5 * kMs;
  const auto clean = m.samples(0, 500 * kMs, dt);
  const Preintegration nominal(clean, noise, Vec3::Zero(), Vec3::Zero());
  std::mt19937 rng(1234);
  constexpr int kRuns = 400;
  Eigen::Matrix<double, 9, 9> S = Eigen::Matrix<double, 9, 9>::Zero();
  for (int run = 0; run < kRuns; ++run) {
    const Preintegration noisy(testing::addWhiteNoise(clean, noise, toSeconds(dt), rng), noise, Vec3::Zero(),
                               Vec3::Zero());
    Eigen::Matrix<double, 9, 1> e;
    e << noisy.alpha() - nominal.alpha(), logSO3(nominal.gamma().conjugate() * noisy.gamma()),
        noisy.beta() - nominal.beta();
    S += e * e.transpose();
  }
  S /= kRuns;
  const Eigen::Matrix<double, 9, 9> P = nominal.covariance().topLeftCorner<9, 9>();
  for (int i = 0; i < 9; ++i) {
    const double ratio = S(i, i) / P(i, i);
    std::printf("  Monte Carlo state %d: sample/predicted variance %.3f\n", i, ratio);
    EXPECT_GT(ratio, 0.75) << "state " << i << " sample " << S(i, i) << " predicted " << P(i, i);
    EXPECT_LT(ratio, 1.3) << "state " << i << " sample " << S(i, i) << " predicted " << P(i, i);
  }
}

TEST(Preintegration, AppendEqualsIntegratingEverything) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  const Vec3 b_a(0.02, 0.01, -0.03), b_g(0.001, -0.002, 0.003);
  const Preintegration whole(m.samples(0, 800 * kMs, 5 * kMs), noise, b_a, b_g);
  Preintegration first(m.samples(0, 300 * kMs, 5 * kMs), noise, b_a, b_g);
  // The second part was linearised elsewhere; append re-integrates its samples at the first part's biases.
  const Preintegration second(m.samples(300 * kMs, 800 * kMs, 5 * kMs), noise, Vec3::Zero(), Vec3::Zero());
  first.append(second);
  EXPECT_EQ(first.startTime(), 0);
  EXPECT_EQ(first.endTime(), 800 * kMs);
  EXPECT_EQ(first.samples().size(), whole.samples().size());
  EXPECT_LT((first.alpha() - whole.alpha()).norm(), 1e-12);
  EXPECT_LT((first.beta() - whole.beta()).norm(), 1e-12);
  EXPECT_LT(first.gamma().angularDistance(whole.gamma()), 1e-12);
  EXPECT_LT((first.jacobian() - whole.jacobian()).norm(), 1e-10);
  EXPECT_LT((first.covariance() - whole.covariance()).norm(), 1e-12 * whole.covariance().norm());

  const Preintegration later(m.samples(900 * kMs, 1000 * kMs, 5 * kMs), noise, b_a, b_g);
  EXPECT_THROW(first.append(later), UsageError);
}

TEST(Preintegration, RepropagateAndBiasMovedFar) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  const Vec3 b_a(0.1, 0.0, 0.0), b_g(0.0, 0.01, 0.0);
  const auto samples = m.samples(0, 500 * kMs, 5 * kMs, b_a, b_g);
  Preintegration pre(samples, noise, Vec3::Zero(), Vec3::Zero());
  EXPECT_FALSE(pre.biasMovedFar(Vec3::Zero(), Vec3::Zero()));
  EXPECT_TRUE(pre.biasMovedFar(Vec3(0.3, 0.0, 0.0), Vec3::Zero()));
  EXPECT_TRUE(pre.biasMovedFar(Vec3::Zero(), Vec3(0.0, 0.0, 0.03)));
  pre.repropagate(b_a, b_g);
  const Preintegration direct(samples, noise, b_a, b_g);
  EXPECT_EQ(pre.alpha(), direct.alpha());
  EXPECT_EQ(pre.covariance(), direct.covariance());
  EXPECT_EQ(pre.linearisedBa(), b_a);
  // With the true biases, prediction follows the motion.
  const ImuState pred = pre.predict(m.state(0, b_a, b_g));
  EXPECT_LT((pred.T_W_B.p - m.position(0.5)).norm(), 1e-4);
}

TEST(Preintegration, SqrtInformationFollowsEveryChangeOfTheCovariance) {
  const testing::SmoothMotion m;
  const ImuNoise noise;
  const Vec3 b_a(0.05, 0.0, -0.02), b_g(0.0, 0.004, 0.0);
  const auto samples = m.samples(0, 300 * kMs, 5 * kMs, b_a, b_g);
  Preintegration pre(std::vector<ImuSample>(samples.begin(), samples.begin() + 30), noise, Vec3::Zero(),
                     Vec3::Zero());
  const auto expectFresh = [&](const char* after) {
    const Mat15 fresh = sqrtInformationOf(pre.covariance());
    EXPECT_EQ(pre.sqrtInformation(), fresh) << after;  // the same computation: bit for bit
    // S^T S is the information matrix.
    const Mat15 info = pre.covariance().inverse();
    EXPECT_LT((fresh.transpose() * fresh - info).norm(), 1e-6 * info.norm()) << after;
  };
  expectFresh("construction");
  pre.push(samples[30]);  // the cached value of before must not survive a new sample
  expectFresh("push");
  pre.repropagate(b_a, b_g);
  expectFresh("repropagate");
  pre.append(Preintegration(std::vector<ImuSample>(samples.begin() + 30, samples.end()), noise, b_a, b_g));
  expectFresh("append");
  const Preintegration copy = pre;
  EXPECT_EQ(copy.sqrtInformation(), pre.sqrtInformation());
}

TEST(Preintegration, PushRejectsTimeGoingBackwardsAndIgnoresDuplicates) {
  Preintegration pre(ImuNoise(), Vec3::Zero(), Vec3::Zero());
  EXPECT_TRUE(pre.empty());
  pre.push({10 * kMs, Vec3(0, 0, 9.81), Vec3::Zero()});
  pre.push({10 * kMs, Vec3(0, 0, 9.81), Vec3::Zero()});
  EXPECT_TRUE(pre.empty());
  pre.push({15 * kMs, Vec3(0, 0, 9.81), Vec3::Zero()});
  EXPECT_FALSE(pre.empty());
  EXPECT_DOUBLE_EQ(pre.sumDt(), 0.005);
  try {
    pre.push({12 * kMs, Vec3::Zero(), Vec3::Zero()});
    FAIL() << "expected UsageError";
  } catch (const UsageError& e) {
    EXPECT_NE(std::string(e.what()).find("12000000"), std::string::npos) << e.what();
  }
}

TEST(Preintegration, OutOfRangeOptionsAreConfigErrorsNamingTheKey) {
  ImuNoise noise;
  noise.acc_noise_density = -1.0;
  try {
    Preintegration pre(noise, Vec3::Zero(), Vec3::Zero());
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("imu.acc_noise_density"), std::string::npos) << e.what();
  }
  PreintegrationOptions opt;
  opt.max_gyr_bias_change = -0.1;
  EXPECT_THROW(Preintegration(ImuNoise(), Vec3::Zero(), Vec3::Zero(), opt), ConfigError);
}

}  // namespace
}  // namespace linnet

namespace linnet {

// A step longer than gap_dt_s adds the unknown motion's variance: (gap_acc_sigma dt)^2 in velocity and
// (gap_gyr_sigma dt)^2 in rotation, on top of what the same step gives without gap noise; normal steps are unchanged.
TEST(Preintegration, GapStepsInflateTheCovarianceByTheUnknownMotion) {
  const ImuNoise noise;
  PreintegrationOptions plain, gap = plain;
  gap.gap_dt_s = 0.015;
  gap.gap_acc_sigma = 2.0;
  gap.gap_gyr_sigma = 0.5;
  const Vec3 a(0.1, -0.2, 9.81), w(0.05, 0.02, -0.1);
  // A 0.1 s step: one sample at 0, the next at 100 ms.
  const std::vector<ImuSample> step = {{0, a, w}, {100 * kMs, a, w}};
  const Preintegration with_gap(step, noise, Vec3::Zero(), Vec3::Zero(), gap);
  const Preintegration without(step, noise, Vec3::Zero(), Vec3::Zero(), plain);
  const double dt = 0.1;
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(with_gap.covariance()(Preintegration::kV + k, Preintegration::kV + k) -
                    without.covariance()(Preintegration::kV + k, Preintegration::kV + k),
                std::pow(2.0 * dt, 2), 2e-2 * std::pow(2.0 * dt, 2));  // + the gyro gap noise rotating a (1.5 %)
    EXPECT_NEAR(with_gap.covariance()(Preintegration::kR + k, Preintegration::kR + k) -
                    without.covariance()(Preintegration::kR + k, Preintegration::kR + k),
                std::pow(0.5 * dt, 2), 1e-2 * std::pow(0.5 * dt, 2));
  }
  // Regular 5 ms steps are below gap_dt_s: identical covariance.
  const auto regular = constantSamples(a, w, 0, 100 * kMs, 5 * kMs);
  const Preintegration r_gap(regular, noise, Vec3::Zero(), Vec3::Zero(), gap);
  const Preintegration r_plain(regular, noise, Vec3::Zero(), Vec3::Zero(), plain);
  EXPECT_EQ(r_gap.covariance(), r_plain.covariance());
}

}  // namespace linnet
