// Static IMU initialisation helpers: statistics of a window of samples, a stillness test, and the rotation
// that aligns the measured specific force with +z of W (DESIGN B1, thesis ch. 5: static gravity alignment).
#pragma once

#include <vector>

#include "linnet/core/types.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

struct StaticDetectionOptions {
  double max_acc_std = 0.25;  // m/s^2: largest per-axis standard deviation of the accelerometer when static
  double max_gyr_std = 0.02;  // rad/s: largest per-axis standard deviation of the gyroscope when static
  double max_gyr_mean =
      0.1;  // rad/s: largest mean angular rate norm when static (a constant rotation is not rest)
  double max_gravity_error = 0.5;  // m/s^2: | |mean acc| - gravity | bound when static
  int min_samples = 10;            // fewer samples is never "static"

  template <class V>
  void visit(V& v) {
    v("max_acc_std", max_acc_std, "accelerometer std bound for rest, m/s^2", 0.0, 10.0);
    v("max_gyr_std", max_gyr_std, "gyroscope std bound for rest, rad/s", 0.0, 1.0);
    v("max_gyr_mean", max_gyr_mean, "mean angular rate bound for rest, rad/s", 0.0, 1.0);
    v("max_gravity_error", max_gravity_error, "bound on | |mean acc| - g | for rest, m/s^2", 0.0, 5.0);
    v("min_samples", min_samples, "minimum number of samples", 2, 100000);
  }
};

/// Mean and per-axis standard deviation of a window of samples.
struct ImuStatistics {
  int count = 0;
  Vec3 acc_mean = Vec3::Zero(), acc_std = Vec3::Zero();  // m/s^2
  Vec3 gyr_mean = Vec3::Zero(), gyr_std = Vec3::Zero();  // rad/s
};

ImuStatistics imuStatistics(const std::vector<ImuSample>& samples);

/// True if the samples look like a body at rest (variances and mean rate small, |mean acc| close to
/// `gravity`).
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
