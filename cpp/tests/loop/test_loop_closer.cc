#include <cmath>

#include <gtest/gtest.h>

#include "linnet/loop/loop_closer.h"
#include "loop_test_scene.h"

namespace linnet {
namespace {

// Keyframes every 0.5 s along the wall and back (60 s); the body is the camera (T_B_C0 = identity).
struct Flight {
  std::vector<Timestamp> t;
  std::vector<Pose> truth, odometry;
};

Flight fly(double yaw_drift, const Vec3& shift) {
  Flight f;
  for (int k = 0; k <= 120; ++k) {
    const double s = 0.5 * k;
    const double x = s <= 30.0 ? -1.5 + 0.1 * s : 1.5 - 0.1 * (s - 30.0);
    f.t.push_back(static_cast<Timestamp>(s * 1e9));
    f.truth.push_back(test::WallScene::cameraAt(Vec3(x, 0.3 * std::sin(0.2 * s), 1.2 + 0.1 * std::cos(0.3 * s)),
                                                0.1 * std::sin(0.15 * s)));
  }
  f.odometry.push_back(f.truth[0]);
  for (std::size_t k = 1; k < f.truth.size(); ++k) {
    const Pose d = f.truth[k - 1].inverse() * f.truth[k];
    Pose next = f.odometry.back() * Pose(d.q, Vec3(d.p + shift));
    f.odometry.push_back(Pose(Mat3(Eigen::AngleAxisd(yaw_drift, Vec3::UnitZ()).toRotationMatrix() * next.R()),
                              next.p));
  }
  return f;
}

TEST(LoopCloser, ClosesTheLoopsOfAFlightThereAndBackAndRemovesTheDrift) {
  const test::WallScene scene;
  const Flight f = fly(0.0002, Vec3(0.004, 0.002, 0.001));  // 1.4 deg of yaw and 0.5 m over the flight
  LoopOptions o;
  o.enabled = true;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  for (std::size_t k = 0; k < f.t.size(); ++k) {
    const cv::Mat image = scene.render(f.truth[k]);
    loop.addKeyframe(f.t[k], f.odometry[k], image, scene.trackedCorners(image, f.truth[k], 150));
  }
  ASSERT_GE(loop.loops().size(), 3u);
  for (const LoopEvent& e : loop.loops()) {
    EXPECT_GE(toSeconds(e.t_new - e.t_old), o.min_time_gap_s);
    EXPECT_GE(e.inliers, o.min_inliers);
  }
  double before = 0.0, after = 0.0;
  for (std::size_t k = 0; k < f.t.size(); ++k) {
    const Pose corrected = loop.correctionAt(f.t[k]) * f.odometry[k];
    before += (f.odometry[k].p - f.truth[k].p).squaredNorm();
    after += (corrected.p - f.truth[k].p).squaredNorm();
  }
  const double rms_before = std::sqrt(before / f.t.size()), rms_after = std::sqrt(after / f.t.size());
  EXPECT_GT(rms_before, 0.15);
  EXPECT_LT(rms_after, 0.35 * rms_before) << rms_before << " -> " << rms_after;
  const Pose last = loop.latestCorrection() * f.odometry.back();
  EXPECT_LT((last.p - f.truth.back().p).norm(), 0.3 * (f.odometry.back().p - f.truth.back().p).norm())
      << (f.odometry.back().p - f.truth.back().p).norm() << " -> " << (last.p - f.truth.back().p).norm();
  // correctionAt before the first keyframe, and at a keyframe's own time.
  EXPECT_LT((loop.correctionAt(-1).p).norm(), 1e-12);
  EXPECT_LT((loop.correctionAt(f.t.back()).p - loop.latestCorrection().p).norm(), 1e-12);
}

TEST(LoopCloser, FindsNoLoopOnAFlightThatNeverComesBack) {
  const test::WallScene scene;
  LoopOptions o;
  o.enabled = true;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  for (int k = 0; k <= 60; ++k) {
    const Pose T = test::WallScene::cameraAt(Vec3(-3.0 + 0.1 * k, 0.0, 1.2), 0.0);
    const cv::Mat image = scene.render(T);
    loop.addKeyframe(static_cast<Timestamp>(k * 5e8), T, image, scene.trackedCorners(image, T, 150));
  }
  EXPECT_TRUE(loop.loops().empty());
  EXPECT_EQ(loop.keyframes(), 61u);
  EXPECT_LT((loop.latestCorrection().p).norm(), 1e-12);
}

}  // namespace
}  // namespace linnet
