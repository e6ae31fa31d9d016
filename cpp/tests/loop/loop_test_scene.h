// A synthetic scene for the loop tests: a textured wall at y = wall_y in W (z up), seen by an undistorted stereo
// pair whose optical axis is horizontal. Images are rendered exactly by the wall's homography.
#pragma once

#include <memory>
#include <random>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"

namespace linnet::test {

struct WallScene {
  double wall_y = 5.0;                   // m
  double x0 = -8.0, z0 = 5.0, res = 0.01;  // texture: x from x0, z down from z0, metres per texel
  cv::Mat texture;
  std::unique_ptr<CameraModel> camera;
  Pose T_C1_C0 = Pose(Mat3::Identity(), Vec3(-0.11, 0.0, 0.0));  // cam1 11 cm right of cam0

  WallScene() {
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> grey(0, 255);
    cv::Mat blocks(80, 160, CV_8U);
    for (int r = 0; r < blocks.rows; ++r)
      for (int c = 0; c < blocks.cols; ++c) blocks.at<unsigned char>(r, c) = static_cast<unsigned char>(grey(rng));
    cv::resize(blocks, texture, cv::Size(1600, 800), 0, 0, cv::INTER_NEAREST);
    cv::GaussianBlur(texture, texture, cv::Size(3, 3), 1.0);
    CameraCalibration calib;
    calib.distortion = "none";
    calib.distortion_coeffs.clear();
    calib.intrinsics = {458.0, 458.0, 376.0, 240.0};
    camera = CameraModel::create(calib);
  }

  /// Camera at `c` looking along +y rotated by `yaw` about z (x right, y down in the image).
  static Pose cameraAt(const Vec3& c, double yaw) {
    Mat3 R0;
    R0.col(0) = Vec3(1, 0, 0);
    R0.col(1) = Vec3(0, 0, -1);
    R0.col(2) = Vec3(0, 1, 0);
    const Mat3 Rz = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
    return Pose(Mat3(Rz * R0), c);
  }

  cv::Mat render(const Pose& T_W_C) const {
    const Mat3 R_C_W = T_W_C.R().transpose();
    Mat3 M;  // (x, z, 1) on the wall -> camera coordinates
    M.col(0) = R_C_W.col(0);
    M.col(1) = R_C_W.col(2);
    M.col(2) = R_C_W * (Vec3(0.0, wall_y, 0.0) - T_W_C.p);
    Mat3 A;  // texel (i, j, 1) -> (x, z, 1)
    A << res, 0.0, x0, 0.0, -res, z0, 0.0, 0.0, 1.0;
    const Mat3 H = camera->K() * M * A;
    cv::Mat Hcv(3, 3, CV_64F);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Hcv.at<double>(r, c) = H(r, c);
    cv::Mat out;
    cv::warpPerspective(texture, out, Hcv, cv::Size(camera->width(), camera->height()), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar(0));
    return out;
  }

  /// The strongest FAST corners of `image` as stereo-matched tracked points (exact cam1 coordinates).
  std::vector<PointObservation> trackedCorners(const cv::Mat& image, const Pose& T_W_C, int n) const {
    std::vector<cv::KeyPoint> kps;
    cv::FAST(image, kps, 20, true);
    cv::KeyPointsFilter::retainBest(kps, n);
    std::vector<PointObservation> out;
    for (std::size_t i = 0; i < kps.size(); ++i) {
      PointObservation p;
      p.id = static_cast<std::int64_t>(i);
      p.px0 = Vec2(kps[i].pt.x, kps[i].pt.y);
      p.uv0 = Vec2((p.px0.x() - camera->cx()) / camera->fx(), (p.px0.y() - camera->cy()) / camera->fy());
      const Vec3 d = T_W_C.R() * Vec3(p.uv0.x(), p.uv0.y(), 1.0);
      if (d.y() <= 1e-6) continue;
      const Vec3 X = T_W_C.p + d * ((wall_y - T_W_C.p.y()) / d.y());
      const Vec3 p_C1 = T_C1_C0 * (T_W_C.inverse() * X);
      p.uv1 = p_C1.head<2>() / p_C1.z();
      p.px1 = Vec2(camera->fx() * p.uv1.x() + camera->cx(), camera->fy() * p.uv1.y() + camera->cy());
      p.has_right = true;
      out.push_back(p);
    }
    return out;
  }
};

}  // namespace linnet::test
