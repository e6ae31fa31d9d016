// The concrete camera models behind CameraModel::create(). Usable directly where the model is known at compile time.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "linnet/camera/camera_model.h"

namespace linnet {

/// Ideal pinhole, no distortion.
class PinholeCamera : public CameraModel {
 public:
  PinholeCamera(int width, int height, double fx, double fy, double cx, double cy)
      : CameraModel(width, height, fx, fy, cx, cy) {}
  std::string distortionName() const override { return "none"; }
  std::vector<double> distortionCoeffs() const override { return {}; }
  Vec2 distort(const Vec2& uv, Mat2* J_px_uv) const override;
  bool undistort(const Vec2& px, Vec2* uv) const override;
  using CameraModel::distort;
};

/// Pinhole + radial-tangential (Brown-Conrady) distortion, OpenCV's order k1 k2 p1 p2 [k3]:
///   r2 = x^2 + y^2, a = 1 + k1 r2 + k2 r2^2 + k3 r2^3
///   xd = a x + 2 p1 x y + p2 (r2 + 2 x^2),  yd = a y + p1 (r2 + 2 y^2) + 2 p2 x y.
class PinholeRadtanCamera : public CameraModel {
 public:
  /// coeffs: 4 or 5 values (k3 = 0 when 4). Throws ConfigError otherwise.
  PinholeRadtanCamera(int width, int height, double fx, double fy, double cx, double cy,
                      const std::vector<double>& coeffs);
  std::string distortionName() const override { return "radtan"; }
  std::vector<double> distortionCoeffs() const override;
  Vec2 distort(const Vec2& uv, Mat2* J_px_uv) const override;
  using CameraModel::distort;

 private:
  double k1_, k2_, p1_, p2_, k3_;
  bool has_k3_;
};

/// Pinhole + equidistant (Kannala-Brandt) fisheye distortion, k1..k4 (Kannala & Brandt 2006, OpenCV cv::fisheye):
///   r = |uv|, theta = atan(r), theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8),
///   distorted normalised point = (theta_d / r) uv.
/// Only rays with theta < pi/2 have normalised coordinates; undistort() returns false beyond.
class PinholeEquidistantCamera : public CameraModel {
 public:
  /// coeffs: exactly 4 values. Throws ConfigError otherwise.
  PinholeEquidistantCamera(int width, int height, double fx, double fy, double cx, double cy,
                           const std::vector<double>& coeffs);
  std::string distortionName() const override { return "equidistant"; }
  std::vector<double> distortionCoeffs() const override { return {k_[0], k_[1], k_[2], k_[3]}; }
  Vec2 distort(const Vec2& uv, Mat2* J_px_uv) const override;
  bool undistort(const Vec2& px, Vec2* uv) const override;
  using CameraModel::distort;

 private:
  std::array<double, 4> k_;
};

}  // namespace linnet
