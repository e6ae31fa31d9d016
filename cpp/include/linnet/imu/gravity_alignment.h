// Static IMU initialisation helpers: statistics of a window of samples, a stillness test, and the rotation
// that aligns the measured specific force with +z of W (DESIGN B1, thesis ch. 5: static gravity alignment).
#pragma once

#include <vector>

#include "linnet/core/types.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

/// Stillness test. A multirotor at rest with its rotors running vibrates strongly (EuRoC V1_01 start: raw
/// accelerometer std ~1 m/s^2, gyroscope ~0.08 rad/s, as large as in flight), so the variances are taken over
/// block means of `averaging_samples` consecutive samples (a low-pass filter that removes the vibration but
/// not the motion). Defaults separate rest from flight on EuRoC V1_01 (averaged gyroscope std: rest <= 0.014
/// rad/s, 1 s flight windows >= 0.05 rad/s; see test_preintegration_euroc.cc).
struct StaticDetectionOptions {
  int averaging_samples = 10;  // samples per block mean before the variance test (10 = 50 ms at 200 Hz)
  double max_acc_std = 0.2;    // m/s^2: largest per-axis std of the block-mean accelerometer at rest
  double max_gyr_std = 0.03;   // rad/s: largest per-axis std of the block-mean gyroscope at rest
  double max_gyr_mean = 0.25;  // rad/s: mean angular rate norm bound (includes the gyro bias, ~0.08 on EuRoC)
  double max_gravity_error = 0.5;  // m/s^2: | |mean acc| - gravity | bound at rest
  int min_samples = 40;            // fewer samples is never "static" (0.2 s at 200 Hz)

  template <class V>
  void visit(V& v) {
    v("averaging_samples", averaging_samples, "samples per block mean (vibration filter)", 1, 1000);
    v("max_acc_std", max_acc_std, "block-mean accelerometer std bound for rest, m/s^2", 0.0, 10.0);
    v("max_gyr_std", max_gyr_std, "block-mean gyroscope std bound for rest, rad/s", 0.0, 1.0);
    v("max_gyr_mean", max_gyr_mean, "mean angular rate bound for rest, rad/s", 0.0, 1.0);
    v("max_gravity_error", max_gravity_error, "bound on | |mean acc| - g | for rest, m/s^2", 0.0, 5.0);
    v("min_samples", min_samples, "minimum number of samples", 2, 100000);
  }
};

/// Mean and per-axis standard deviation of a window of samples.
struct ImuStatistics {
  int count = 0;                                         // samples
  Vec3 acc_mean = Vec3::Zero(), acc_std = Vec3::Zero();  // m/s^2
  Vec3 gyr_mean = Vec3::Zero(), gyr_std = Vec3::Zero();  // rad/s
};

/// Means over all samples; standard deviations (n - 1 normalised) over the means of consecutive blocks of
/// `averaging_samples` samples (a trailing partial block is left out of the std); 1 = raw sample std.
ImuStatistics imuStatistics(const std::vector<ImuSample>& samples, int averaging_samples = 1);

/// True if the samples look like a body at rest: enough samples, block-mean stds and mean rate small, and
/// |mean acc| close to `gravity`.
bool isStatic(const std::vector<ImuSample>& samples, const StaticDetectionOptions& options,
              double gravity = 9.81);

/// R_W_B with zero yaw such that R_W_B * f_B points along +z of W, where f_B is the mean specific force at
/// rest. Throws InputError if f_B is (near) zero.
Quat gravityAlignedRotation(const Vec3& mean_specific_force_B);

/// The same from a window of samples (their mean accelerometer reading). Throws InputError if empty.
Quat gravityAlignedRotation(const std::vector<ImuSample>& samples);

/// Yaw (rotation about z of W, ZYX convention) of a rotation R_W_B, radians.
double yawOf(const Quat& q_W_B);

}  // namespace linnet
