// Sensor calibration files in the formats of the EuRoC ASL layout and of Kalibr (Furgale et al., IROS 2013;
// Rehder et al., ICRA 2016), the calibration tool most visual-inertial datasets ship results of.
//
//  * EuRoC camN/sensor.yaml: T_BS (camera in body), rate_hz, resolution, camera_model, intrinsics,
//    distortion_model, distortion_coefficients.
//  * EuRoC imu0/sensor.yaml: gyroscope_/accelerometer_ noise_density and random_walk, rate_hz, T_BS.
//  * Kalibr camchain.yaml: cam0, cam1, ... each with T_cam_imu (IMU -> camera, i.e. T_C_I), camera_model,
//    intrinsics, distortion_model, distortion_coeffs, resolution, timeshift_cam_imu; cam1 may give
//    T_cn_cnm1 (cam0 -> cam1) instead of T_cam_imu.
//  * Kalibr imu.yaml: the noise keys above (under imu0: or at the top level) with update_rate.
//
// Distortion names: "radial-tangential" / "radtan" / "plumb_bob" -> "radtan" (k1 k2 p1 p2);
// "equidistant" / "fisheye" / "kannala_brandt" -> "equidistant" (k1..k4); "none" -> "none". Only the pinhole
// projection is supported. Every problem is an InputError naming the file, the line and the key.
#pragma once

#include <string>
#include <vector>

#include "linnet/camera/camera_model.h"
#include "linnet/core/pose.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

/// One camera's EuRoC sensor.yaml -> calibration (T_B_C = T_BS).
CameraCalibration readCameraSensorYaml(const std::string& path);

/// EuRoC imu0/sensor.yaml or Kalibr imu.yaml -> noise parameters (gravity keeps its default). The IMU's
/// pose in the body frame (T_BS; Kalibr: T_i_b inverted) is returned through `T_B_S` when given (identity
/// if absent).
ImuNoise readImuSensorYaml(const std::string& path, Pose* T_B_S = nullptr);

/// A Kalibr camchain: the cameras in order cam0, cam1, ... with T_B_C = T_cam_imu^-1 (B = IMU), and each
/// camera's timeshift_cam_imu in seconds (t_imu = t_cam + shift; 0 if absent). rate_hz is left at its
/// default: camchains do not hold it.
struct KalibrCamchain {
  std::vector<CameraCalibration> cameras;
  std::vector<double> timeshift_cam_imu_s;
};
KalibrCamchain readKalibrCamchain(const std::string& path);

}  // namespace linnet
