// Point tracking under known camera rotation on a real EuRoC frame: each frame is the first one re-rendered through
// the calibrated (distorted) camera after a pure rotation, so every tracked point has a known true position.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/imgproc.hpp>

#include "features/test_point_data.h"
#include "linnet/camera/camera_model.h"
#include "linnet/core/pose.h"
#include "linnet/features/point_tracker.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

// Renders what cam sees after rotating by R_cur_first (p_cur = R p_first) from the rays of the first image.
// rays: per pixel of the output, its normalised coordinates (undistorted), NaN where undistortion failed.
cv::Mat renderRotated(const cv::Mat& first, const CameraModel& cam, const std::vector<Vec2>& rays,
                      const Mat3& R_cur_first) {
  cv::Mat mx(first.size(), CV_32F), my(first.size(), CV_32F);
  const Mat3 R_first_cur = R_cur_first.transpose();
  for (int v = 0; v < first.rows; ++v)
    for (int u = 0; u < first.cols; ++u) {
      const Vec2& uv = rays[static_cast<std::size_t>(v) * first.cols + u];
      float sx = -1.f, sy = -1.f;
      const Vec3 a = R_first_cur * Vec3(uv.x(), uv.y(), 1.0);
      if (std::isfinite(uv.x()) && a.z() > 1e-6) {
        const Vec2 px = cam.distort(Vec2(a.x() / a.z(), a.y() / a.z()));
        sx = static_cast<float>(px.x());
        sy = static_cast<float>(px.y());
      }
      mx.at<float>(v, u) = sx;
      my.at<float>(v, u) = sy;
    }
  cv::Mat out;
  cv::remap(first, out, mx, my, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

TEST(PointMotion, TracksFollowAKnownRotationThroughTheDistortion) {
  LINNET_REQUIRE_SHARED_DATA(testing::eurocMicroDir());
  const auto root = testing::eurocMicroDir();
  const CameraCalibration calib = testing::readEurocCamera(root / "mav0" / "cam0" / "sensor.yaml");
  const auto cam = CameraModel::create(calib);
  const cv::Mat first = testing::readEurocStereo(root, 1).front().left;
  std::vector<Vec2> rays(first.total());
  for (int v = 0; v < first.rows; ++v)
    for (int u = 0; u < first.cols; ++u) {
      Vec2 uv;
      rays[static_cast<std::size_t>(v) * first.cols + u] =
          cam->undistort(Vec2(u, v), &uv) ? uv : Vec2(std::nan(""), std::nan(""));
    }

  // 12 frames turning about the camera's y and x axes by ~1.2 degrees per frame (~10 px of flow per frame).
  const Vec3 w_step(0.004, 0.02, 0.003);
  // With CLAHE (the default) its tiles stay put while the content moves, which biases KLT a little: both are measured.
  for (const auto& [predict, clahe] : {std::pair{false, false}, std::pair{true, false}, std::pair{true, true}}) {
    PointTrackerOptions opt;
    opt.clahe = clahe;
    PointTracker tracker(opt, *cam, nullptr, Pose());
    std::map<std::int64_t, Vec3> first_ray;  // bearing in the first camera frame at detection
    std::vector<double> err_px;
    int long_tracks = 0;
    Mat3 R_prev = Mat3::Identity();
    for (int k = 0; k < 12; ++k) {
      const Mat3 R_k = expSO3(w_step * k).toRotationMatrix();  // R_cur_first
      const cv::Mat img = k == 0 ? first : renderRotated(first, *cam, rays, R_k);
      if (predict && k > 0) tracker.setRotationPrediction(R_k * R_prev.transpose());
      std::vector<PointObservation> obs;
      tracker.track(k * 50'000'000LL, img, cv::Mat(), &obs);
      EXPECT_GE(obs.size(), 120u) << "frame " << k;
      for (const auto& o : obs) {
        const Vec3 ray_now(o.uv0.x(), o.uv0.y(), 1.0);
        if (o.track_length == 1) {
          first_ray[o.id] = R_k.transpose() * ray_now;  // where this point lies in the first frame
          continue;
        }
        const Vec3 a = R_k * first_ray.at(o.id);
        Vec2 truth;
        ASSERT_TRUE(cam->project(a, &truth));
        err_px.push_back((truth - o.px0).norm());
        if (k == 11 && o.track_length == 12) ++long_tracks;
      }
      R_prev = R_k;
    }
    std::sort(err_px.begin(), err_px.end());
    const double med = err_px[err_px.size() / 2], p95 = err_px[err_px.size() * 95 / 100];
    std::printf("[points] rotation sequence (prediction %d, clahe %d): %zu tracked observations, error median %.3f px, "
                "p95 %.3f px, %d tracks over all 12 frames\n",
                predict, clahe, err_px.size(), med, p95, long_tracks);
    EXPECT_LT(med, clahe ? 0.3 : 0.12);
    EXPECT_LT(p95, clahe ? 1.5 : 0.6);
    EXPECT_GE(long_tracks, 60);
  }
}

}  // namespace
}  // namespace linnet
