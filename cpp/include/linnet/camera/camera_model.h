// Camera models: projection with distortion, and undistortion to normalised coordinates.
//
// Models (DESIGN A1 "camera"):
//   pinhole + radtan       Brown-Conrady radial-tangential, coefficients k1 k2 p1 p2 [k3] (OpenCV order; EuRoC/Kalibr)
//   pinhole + equidistant  Kannala-Brandt fisheye, k1 k2 k3 k4 (Kannala & Brandt, TPAMI 2006; Kalibr "equidistant",
//                          OpenCV cv::fisheye), e.g. TUM-VI
//   pinhole + none         ideal pinhole
// This header needs no OpenCV: the estimator layer includes it.
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
  std::string distortion = "radtan";            // "radtan" (k1 k2 p1 p2 [k3]) | "equidistant" (k1 k2 k3 k4) | "none"
  int width = 752;                              // pixels
  int height = 480;                             // pixels
  std::array<double, 4> intrinsics{458.654, 457.296, 367.215, 248.375};  // fx fy cx cy, pixels
  std::vector<double> distortion_coeffs{-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  Pose T_B_C;                                   // camera in body (IMU) frame, p_B = T_B_C * p_C
  double rate_hz = 20.0;                        // frame rate, Hz

  /// Options protocol (core/options.h). T_B_C is written as a 4x4 row-major list of 16 numbers (Kalibr's T_BS data).
  template <class V>
  void visit(V& v) {
    v.choice("model", model, "projection model", {"pinhole"});
    v.choice("distortion", distortion, "distortion model: radtan (k1 k2 p1 p2 [k3]) | equidistant (k1..k4) | none",
             {"radtan", "equidistant", "none"});
    v("width", width, "image width, pixels", 1, 100000);
    v("height", height, "image height, pixels", 1, 100000);
    v("intrinsics", intrinsics, "fx fy cx cy, pixels");
    v("distortion_coeffs", distortion_coeffs, "radtan: k1 k2 p1 p2 [k3]; equidistant: k1 k2 k3 k4; none: empty");
    v("T_B_C", T_B_C, "camera -> body transform (4x4, row-major, 16 numbers)");
    v("rate_hz", rate_hz, "frame rate, Hz", 0.1, 10000.0);
  }
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
  /// Pinhole matrix [[fx 0 cx] [0 fy cy] [0 0 1]].
  Mat3 K() const;
  /// "radtan" | "equidistant" | "none".
  virtual std::string distortionName() const = 0;
  /// The coefficients this model was built with (as in CameraCalibration::distortion_coeffs).
  virtual std::vector<double> distortionCoeffs() const = 0;

  /// Normalised coordinates (x/z, y/z) -> distorted pixel coordinates. If J_px_uv is given, it receives the
  /// 2x2 Jacobian d(px)/d(uv).
  virtual Vec2 distort(const Vec2& uv, Mat2* J_px_uv) const = 0;
  Vec2 distort(const Vec2& uv) const { return distort(uv, nullptr); }

  /// Distorted pixel coordinates -> normalised coordinates (Newton iterations). Returns false (uv untouched or
  /// partial) when the iteration does not reach a reprojection residual below 1e-10 in normalised units
  /// (about 5e-8 px), or when the pixel lies outside the model's valid (invertible) region.
  virtual bool undistort(const Vec2& px, Vec2* uv) const;

  /// Point in the camera frame -> pixel. Returns false when behind the camera (z <= 1e-6).
  bool project(const Vec3& p_C, Vec2* px) const {
    if (p_C.z() <= 1e-6) return false;
    *px = distort(Vec2(p_C.x() / p_C.z(), p_C.y() / p_C.z()));
    return true;
  }
  /// Pixel -> unit bearing vector in the camera frame (z > 0). Returns false when undistort() fails.
  bool unproject(const Vec2& px, Vec3* bearing) const;

  bool inImage(const Vec2& px, double border = 0.0) const {
    return px.x() >= border && px.y() >= border && px.x() <= width_ - 1 - border && px.y() <= height_ - 1 - border;
  }

  /// Batch distortion: px[i] = distort(uv[i]).
  std::vector<Vec2> distortPoints(const std::vector<Vec2>& uv) const;
  /// Batch undistortion. uv gets one entry per input (zero where it failed); ok (optional) gets 1/0 per input.
  /// Returns the number of points that converged.
  int undistortPoints(const std::vector<Vec2>& px, std::vector<Vec2>* uv, std::vector<unsigned char>* ok) const;

  /// Undistortion map for cv::remap (CV_32FC1 maps wrap these vectors as cv::Mat(out_height, out_width, CV_32F,
  /// map_x->data())): for every pixel (u, v) of an ideal pinhole image with matrix K_new, the source pixel of this
  /// distorted camera. Row-major, out_width * out_height entries each.
  void undistortionMap(const Mat3& K_new, int out_width, int out_height, std::vector<float>* map_x,
                       std::vector<float>* map_y) const;

  /// Builds the model named by calib.distortion. Also accepts Kalibr's names "radial-tangential" and
  /// "fisheye"/"kannala_brandt" for the distortion. Throws ConfigError on an unknown model, a wrong coefficient
  /// count, non-positive focal lengths or image size.
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
  /// Extrinsic from cam0 to cam1: p_C1 = T_C1_C0 * p_C0. Requires a stereo rig (UsageError otherwise).
  Pose T_C1_C0() const;
};

}  // namespace linnet
