// Camera models: projection with distortion, and undistortion to normalised coordinates.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

/// Intrinsic calibration as found in a EuRoC/Kalibr sensor.yaml.
struct CameraCalibration {
  std::string model = "pinhole";                // camera model: "pinhole"
  std::string distortion = "radtan";            // "radtan" (k1 k2 p1 p2) | "equidistant" (k1 k2 k3 k4) | "none"
  int width = 752;                              // pixels
  int height = 480;                             // pixels
  std::array<double, 4> intrinsics{458.654, 457.296, 367.215, 248.375};  // fx fy cx cy, pixels
  std::vector<double> distortion_coeffs{-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  Pose T_B_C;                                   // camera in body (IMU) frame
  double rate_hz = 20.0;                        // frame rate
};

/// A calibrated camera. Pixel <-> normalised (undistorted, z = 1) coordinates.
class CameraModel {
 public:
  virtual ~CameraModel() = default;

  int width() const { return width_; }
  int height() const { return height_; }
  double fx() const { return fx_; }
  double fy() const { return fy_; }
  double cx() const { return cx_; }
  double cy() const { return cy_; }

  /// Normalised coordinates (x/z, y/z) -> distorted pixel coordinates.
  virtual Vec2 distort(const Vec2& uv) const = 0;
  /// Distorted pixel coordinates -> normalised coordinates. Returns false if it does not converge.
  virtual bool undistort(const Vec2& px, Vec2* uv) const = 0;

  /// Point in the camera frame -> pixel. Returns false when behind the camera (z <= 1e-6).
  bool project(const Vec3& p_C, Vec2* px) const {
    if (p_C.z() <= 1e-6) return false;
    *px = distort(Vec2(p_C.x() / p_C.z(), p_C.y() / p_C.z()));
    return true;
  }
  bool inImage(const Vec2& px, double border = 0.0) const {
    return px.x() >= border && px.y() >= border && px.x() <= width_ - 1 - border && px.y() <= height_ - 1 - border;
  }

  /// Builds the model named by calib.distortion. Throws ConfigError on an unknown model or wrong coefficient count.
  static std::unique_ptr<CameraModel> create(const CameraCalibration& calib);

 protected:
  CameraModel(int width, int height, double fx, double fy, double cx, double cy)
      : width_(width), height_(height), fx_(fx), fy_(fy), cx_(cx), cy_(cy) {}
  int width_, height_;
  double fx_, fy_, cx_, cy_;
};

/// A stereo (or mono: one camera) rig with its extrinsics.
struct CameraRig {
  std::vector<CameraCalibration> cameras;  // cam0 (left), optionally cam1 (right)
  bool stereo() const { return cameras.size() >= 2; }
};

}  // namespace linnet
