// Triangulation on real data: the first stereo pair of EuRoC V1_01_easy (shared data), corners tracked left
// -> right with KLT, undistorted with the calibrated camera models, triangulated with the Kalibr extrinsics.
// Cross-checked against OpenCV's own linear triangulation on the same normalised coordinates.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/geometry/triangulation.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

/// Reads a Kalibr/EuRoC camera sensor.yaml (it carries the %YAML:1.0 header that cv::FileStorage needs).
CameraCalibration readSensorYaml(const std::filesystem::path& file) {
  cv::FileStorage fs(file.string(), cv::FileStorage::READ);
  EXPECT_TRUE(fs.isOpened()) << file;
  CameraCalibration c;
  std::vector<double> T, intr, dist;
  std::vector<int> res;
  fs["T_BS"]["data"] >> T;
  fs["intrinsics"] >> intr;
  fs["distortion_coefficients"] >> dist;
  fs["resolution"] >> res;
  EXPECT_EQ(T.size(), 16u) << file;
  EXPECT_EQ(intr.size(), 4u) << file;
  EXPECT_EQ(res.size(), 2u) << file;
  Mat4 M;
  for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = T[static_cast<std::size_t>(i)];
  c.T_B_C = Pose::fromMatrix(M);
  std::copy(intr.begin(), intr.end(), c.intrinsics.begin());
  c.distortion = "radtan";
  c.distortion_coeffs = dist;
  c.width = res[0];
  c.height = res[1];
  return c;
}

std::filesystem::path firstImage(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.path().extension() == ".png") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files.empty() ? std::filesystem::path() : files.front();
}

TEST(TriangulationEuroc, StereoPairGivesPlausibleDepthsAndMatchesOpenCv) {
  const std::filesystem::path root = testing::eurocMicroDir();
  LINNET_REQUIRE_SHARED_DATA(root);
  const std::filesystem::path mav = root / "mav0";
  const CameraCalibration calib0 = readSensorYaml(mav / "cam0" / "sensor.yaml");
  const CameraCalibration calib1 = readSensorYaml(mav / "cam1" / "sensor.yaml");
  const auto cam0 = CameraModel::create(calib0), cam1 = CameraModel::create(calib1);
  const std::filesystem::path left_file = firstImage(mav / "cam0" / "data");
  const std::filesystem::path right_file = mav / "cam1" / "data" / left_file.filename();
  const cv::Mat left = cv::imread(left_file.string(), cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(right_file.string(), cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(left.empty()) << left_file;
  ASSERT_FALSE(right.empty()) << right_file;

  // Corners on the left, KLT to the right with a backward check.
  std::vector<cv::Point2f> pl, pr, back;
  cv::goodFeaturesToTrack(left, pl, 400, 0.01, 12.0);
  ASSERT_GT(pl.size(), 100u);
  std::vector<uchar> st, st_back;
  std::vector<float> err;
  cv::calcOpticalFlowPyrLK(left, right, pl, pr, st, err, cv::Size(21, 21), 3);
  cv::calcOpticalFlowPyrLK(right, left, pr, back, st_back, err, cv::Size(21, 21), 3);

  std::vector<Vec2> uv0, uv1;
  for (std::size_t i = 0; i < pl.size(); ++i) {
    if (!st[i] || !st_back[i] || cv::norm(pl[i] - back[i]) > 1.0) continue;
    Vec2 a, b;
    if (!cam0->undistort(Vec2(pl[i].x, pl[i].y), &a) || !cam1->undistort(Vec2(pr[i].x, pr[i].y), &b))
      continue;
    uv0.push_back(a);
    uv1.push_back(b);
  }
  ASSERT_GT(uv0.size(), 60u);

  // Body frame as world: the cameras sit at their extrinsics.
  const Pose T_W_C0 = calib0.T_B_C, T_W_C1 = calib1.T_B_C;
  const double focal = cam0->fx();
  int good = 0;
  std::vector<double> depths;
  cv::Mat P0(3, 4, CV_64F), P1(3, 4, CV_64F);
  for (int which = 0; which < 2; ++which) {
    const Pose T_C_W = (which == 0 ? T_W_C0 : T_W_C1).inverse();
    cv::Mat& P = which == 0 ? P0 : P1;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) P.at<double>(r, c) = T_C_W.R()(r, c);
      P.at<double>(r, 3) = T_C_W.p(r);
    }
  }
  cv::Mat x0(2, static_cast<int>(uv0.size()), CV_64F), x1(2, static_cast<int>(uv0.size()), CV_64F);
  std::vector<Vec3> ours(uv0.size());
  std::vector<bool> ok(uv0.size());
  for (std::size_t i = 0; i < uv0.size(); ++i) {
    x0.at<double>(0, static_cast<int>(i)) = uv0[i].x();
    x0.at<double>(1, static_cast<int>(i)) = uv0[i].y();
    x1.at<double>(0, static_cast<int>(i)) = uv1[i].x();
    x1.at<double>(1, static_cast<int>(i)) = uv1[i].y();
    double parallax = 0.0;
    ok[i] = triangulateTwoView(T_W_C0, uv0[i], T_W_C1, uv1[i], &ours[i], &parallax);
    if (!ok[i]) continue;
    const double z = depthInCamera(T_W_C0, ours[i]);
    const double err_px = focal * meanReprojectionError({T_W_C0, T_W_C1}, {uv0[i], uv1[i]}, ours[i]);
    if (z > 0.3 && z < 30.0 && err_px < 1.0) {
      ++good;
      depths.push_back(z);
    }
  }
  // Almost every KLT stereo match is a valid point in front of the rig with sub-pixel reprojection error.
  EXPECT_GT(good, static_cast<int>(0.9 * static_cast<double>(uv0.size()))) << good << " of " << uv0.size();
  // The Vicon room of V1_01 seen from the start pose: depths of about a metre to several metres.
  std::nth_element(depths.begin(), depths.begin() + static_cast<long>(depths.size() / 2), depths.end());
  const double median = depths[depths.size() / 2];
  EXPECT_GT(median, 1.0);
  EXPECT_LT(median, 10.0);

  // OpenCV's linear triangulation of the same data (an independent implementation of the DLT).
  cv::Mat X;
  cv::triangulatePoints(P0, P1, x0, x1, X);
  int compared = 0;
  for (std::size_t i = 0; i < uv0.size(); ++i) {
    if (!ok[i]) continue;
    const int c = static_cast<int>(i);
    const double w = X.at<double>(3, c);
    if (std::abs(w) < 1e-12) continue;
    const Vec3 p_cv(X.at<double>(0, c) / w, X.at<double>(1, c) / w, X.at<double>(2, c) / w);
    const double z = depthInCamera(T_W_C0, ours[i]);
    if (z <= 0.3 || z >= 30.0) continue;
    // Both are linear (algebraic) solutions with different row weights, so they agree to within the noise;
    // after our Gauss-Newton refinement the reprojection error must be no larger than OpenCV's.
    EXPECT_LT((p_cv - ours[i]).norm(), 0.02 * z) << "point " << i << " depth " << z;
    Vec3 refined = ours[i];
    ASSERT_TRUE(refinePoint({T_W_C0, T_W_C1}, {uv0[i], uv1[i]}, &refined, 10));
    // The refinement minimises the sum of squared normalised errors; compare that.
    auto sq = [&](const Vec3& p) {
      double sum = 0.0;
      for (const auto& [T, uv] : {std::pair{T_W_C0, uv0[i]}, std::pair{T_W_C1, uv1[i]}}) {
        const Vec3 pc = T.inverse() * p;
        sum += (Vec2(pc.x() / pc.z(), pc.y() / pc.z()) - uv).squaredNorm();
      }
      return sum;
    };
    EXPECT_LE(sq(refined), sq(p_cv) * (1.0 + 1e-9) + 1e-18) << "point " << i;
    ++compared;
  }
  EXPECT_GT(compared, 60);
  std::printf("[euroc stereo] %zu matches, %d valid (median depth %.2f m), %d compared with OpenCV\n",
              uv0.size(), good, median, compared);
}

}  // namespace
}  // namespace linnet
