// IMU samples and noise parameters.
#pragma once

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

/// One IMU reading in the body (IMU) frame.
struct ImuSample {
  Timestamp t = 0;          // ns
  Vec3 acc = Vec3::Zero();  // specific force, m/s^2
  Vec3 gyr = Vec3::Zero();  // angular rate, rad/s
};

/// Continuous-time noise densities (Kalibr / EuRoC imu0 sensor.yaml convention). Defaults: EuRoC ADIS16448.
struct ImuNoise {
  double acc_noise_density = 2.0e-3;     // m/s^2/sqrt(Hz)   (accelerometer_noise_density)
  double gyr_noise_density = 1.6968e-4;  // rad/s/sqrt(Hz)   (gyroscope_noise_density)
  double acc_random_walk = 3.0e-3;       // m/s^3/sqrt(Hz)   (accelerometer_random_walk)
  double gyr_random_walk = 1.9393e-5;    // rad/s^2/sqrt(Hz) (gyroscope_random_walk)
  double rate_hz = 200.0;                // nominal sample rate
  double gravity = 9.81;                 // m/s^2, along -z of W

  template <class V>
  void visit(V& v) {
    v("acc_noise_density", acc_noise_density, "m/s^2/sqrt(Hz)", 0.0, 10.0);
    v("gyr_noise_density", gyr_noise_density, "rad/s/sqrt(Hz)", 0.0, 10.0);
    v("acc_random_walk", acc_random_walk, "m/s^3/sqrt(Hz)", 0.0, 10.0);
    v("gyr_random_walk", gyr_random_walk, "rad/s^2/sqrt(Hz)", 0.0, 10.0);
    v("rate_hz", rate_hz, "nominal IMU rate, Hz", 1.0, 10000.0);
    v("gravity", gravity, "gravity magnitude, m/s^2", 9.0, 10.5);
  }

  /// Gravity vector in W: (0, 0, -gravity).
  Vec3 gravityVector() const { return Vec3(0.0, 0.0, -gravity); }
};

/// Navigation state of the body at one instant: pose T_W_B, velocity in W, biases in B.
struct ImuState {
  Timestamp t = 0;          // ns
  Pose T_W_B;               // body (IMU) pose in W
  Vec3 v_W = Vec3::Zero();  // m/s
  Vec3 b_a = Vec3::Zero();  // accelerometer bias, m/s^2
  Vec3 b_g = Vec3::Zero();  // gyroscope bias, rad/s
};

}  // namespace linnet
