// Gravity alignment from the mean specific force, and the stillness test.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "imu/imu_test_motion.h"
#include "linnet/core/error.h"
#include "linnet/imu/gravity_alignment.h"

namespace linnet {
namespace {

constexpr Timestamp kMs = 1'000'000;

std::vector<ImuSample> restSamples(const Quat& q_W_B, const ImuNoise& noise, const Vec3& b_a, const Vec3& b_g,
                                   std::mt19937& rng, int count = 200) {
  const Vec3 f_B = q_W_B.conjugate() * Vec3(0.0, 0.0, noise.gravity);
  std::vector<ImuSample> out;
  for (int k = 0; k < count; ++k) out.push_back({k * 5 * kMs, f_B + b_a, b_g});
  return testing::addWhiteNoise(out, noise, 0.005, rng);
}

TEST(GravityAlignment, RecoversRollAndPitchWithZeroYaw) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  const ImuNoise noise;
  for (int trial = 0; trial < 20; ++trial) {
    const Quat q_true = expSO3(Vec3(0.8 * n(rng), 0.8 * n(rng), 3.0 * n(rng)));
    const auto samples = restSamples(q_true, noise, Vec3::Zero(), Vec3::Zero(), rng);
    const Quat q = gravityAlignedRotation(samples);
    // Gravity direction: R_W_B f_B is along +z.
    const Vec3 up = q * imuStatistics(samples).acc_mean.normalized();
    EXPECT_LT((up - Vec3::UnitZ()).norm(), 1e-12);
    EXPECT_NEAR(yawOf(q), 0.0, 1e-12);
    // Same tilt as the truth: they differ by a rotation about z only.
    const Vec3 z_true = q_true.conjugate() * Vec3::UnitZ(), z_est = q.conjugate() * Vec3::UnitZ();
    EXPECT_LT(std::acos(std::min(1.0, z_true.dot(z_est))), 2e-3);  // noise-limited: ~0.14 mrad per axis
    const Quat yaw_only = q * q_true.conjugate();
    EXPECT_LT(std::abs(std::abs(yaw_only.z()) - yaw_only.vec().norm()), 2e-3);
  }
}

TEST(GravityAlignment, ZeroSpecificForceIsAnInputError) {
  EXPECT_THROW(gravityAlignedRotation(Vec3::Zero()), InputError);
  EXPECT_THROW(gravityAlignedRotation(std::vector<ImuSample>{}), InputError);
  // Upside down is fine.
  const Quat q = gravityAlignedRotation(Vec3(0.0, 0.0, -9.81));
  EXPECT_LT((q * Vec3(0.0, 0.0, -1.0) - Vec3::UnitZ()).norm(), 1e-12);
}

TEST(StaticDetection, RestIsStaticMotionIsNot) {
  std::mt19937 rng(5);
  const ImuNoise noise;
  const StaticDetectionOptions opt;
  const Quat q(Eigen::AngleAxisd(0.3, Vec3(1.0, 1.0, 0.0).normalized()));
  EXPECT_TRUE(isStatic(restSamples(q, noise, Vec3(0.05, 0.0, -0.1), Vec3(0.003, 0.0, 0.0), rng), opt, 9.81));
  // Too few samples.
  EXPECT_FALSE(isStatic(restSamples(q, noise, Vec3::Zero(), Vec3::Zero(), rng, 5), opt, 9.81));
  // The smooth test motion (accelerations ~1 m/s^2, rotation) is not static.
  const testing::SmoothMotion m;
  EXPECT_FALSE(isStatic(m.samples(0, 1000 * kMs, 5 * kMs), opt, 9.81));
  // Constant rotation without vibration: the mean-rate bound rejects it.
  std::vector<ImuSample> spinning;
  for (int k = 0; k < 100; ++k) spinning.push_back({k * 5 * kMs, Vec3(0, 0, 9.81), Vec3(0, 0, 0.5)});
  EXPECT_FALSE(isStatic(spinning, opt, 9.81));
  // Free fall (no specific force) is not rest.
  std::vector<ImuSample> falling;
  for (int k = 0; k < 100; ++k) falling.push_back({k * 5 * kMs, Vec3::Zero(), Vec3::Zero()});
  EXPECT_FALSE(isStatic(falling, opt, 9.81));
}

TEST(StaticDetection, BlockAveragingIgnoresRotorVibration) {
  // Rest with a 47 Hz vibration (1.5 m/s^2, 0.12 rad/s): raw variances look like flight, block means do not.
  std::mt19937 rng(8);
  const ImuNoise noise;
  const Quat q(Eigen::AngleAxisd(0.1, Vec3::UnitX()));
  auto samples = restSamples(q, noise, Vec3::Zero(), Vec3(0.0, 0.0, 0.08), rng, 200);
  for (ImuSample& s : samples) {
    const double ph = 2.0 * M_PI * 47.0 * toSeconds(s.t);
    s.acc += Vec3(1.5 * std::sin(ph), 1.0 * std::cos(ph), 0.8 * std::sin(ph + 1.0));
    s.gyr += Vec3(0.12 * std::cos(ph), 0.08 * std::sin(ph), 0.05 * std::cos(ph + 0.5));
  }
  StaticDetectionOptions opt;
  EXPECT_TRUE(isStatic(samples, opt, 9.81));
  const ImuStatistics raw = imuStatistics(samples), avg = imuStatistics(samples, opt.averaging_samples);
  EXPECT_GT(raw.acc_std.maxCoeff(), 0.8);
  EXPECT_LT(avg.acc_std.maxCoeff(), 0.2);
  EXPECT_LT(avg.gyr_std.maxCoeff(), 0.03);
  opt.averaging_samples = 1;
  EXPECT_FALSE(isStatic(samples, opt, 9.81));
}

TEST(StaticDetection, StatisticsAreMeanAndSampleStd) {
  std::vector<ImuSample> s = {{0, Vec3(1, 2, 3), Vec3(0, 0, 0)}, {1, Vec3(3, 2, 1), Vec3(0, 0, 2)}};
  const ImuStatistics st = imuStatistics(s);
  EXPECT_EQ(st.count, 2);
  EXPECT_LT((st.acc_mean - Vec3(2, 2, 2)).norm(), 1e-15);
  EXPECT_LT((st.acc_std - Vec3(std::sqrt(2.0), 0.0, std::sqrt(2.0))).norm(), 1e-15);
  EXPECT_LT((st.gyr_std - Vec3(0.0, 0.0, std::sqrt(2.0))).norm(), 1e-15);
  // Blocks of two: means (2, 2, 2) and (4, 4, 4) -> std sqrt(2) per axis; the odd fifth sample only enters
  // the mean.
  s = {{0, Vec3::Constant(1), Vec3::Zero()},
       {1, Vec3::Constant(3), Vec3::Zero()},
       {2, Vec3::Constant(4), Vec3::Zero()},
       {3, Vec3::Constant(4), Vec3::Zero()},
       {4, Vec3::Constant(8), Vec3::Zero()}};
  const ImuStatistics b = imuStatistics(s, 2);
  EXPECT_EQ(b.count, 5);
  EXPECT_LT((b.acc_mean - Vec3::Constant(4)).norm(), 1e-15);
  EXPECT_LT((b.acc_std - Vec3::Constant(std::sqrt(2.0))).norm(), 1e-15);
}

}  // namespace
}  // namespace linnet
