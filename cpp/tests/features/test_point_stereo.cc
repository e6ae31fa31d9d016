// Unrectified stereo matching of points on a synthetic plane with known depth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/error.h"
#include "linnet/features/point_detection.h"
#include "linnet/features/point_stereo.h"

namespace linnet {
namespace {

std::unique_ptr<CameraModel> pinhole() {
  CameraCalibration c;
  c.distortion = "none";
  c.distortion_coeffs = {};
  c.width = 640;
  c.height = 480;
  c.intrinsics = {400.0, 400.0, 320.0, 240.0};
  return CameraModel::create(c);
}

cv::Mat texture() {
  cv::Mat a(480, 640, CV_32F), b(60, 80, CV_32F);
  cv::RNG rng(9);
  rng.fill(a, cv::RNG::UNIFORM, 0.0, 255.0);
  rng.fill(b, cv::RNG::UNIFORM, 0.0, 255.0);
  cv::GaussianBlur(a, a, cv::Size(0, 0), 1.5);
  cv::resize(b, b, a.size(), 0, 0, cv::INTER_CUBIC);
  cv::Mat m = 0.6 * a + 0.4 * b, img;
  cv::normalize(m, m, 0, 255, cv::NORM_MINMAX);
  m.convertTo(img, CV_8U);
  return img;
}

struct StereoScene {
  std::unique_ptr<CameraModel> cam = pinhole();
  std::vector<cv::Mat> pyr0, pyr1;
  std::vector<cv::Point2f> px0;
  std::vector<Vec2> uv0;
};

// Fronto-parallel plane at depth Z, baseline b along x: the right image is the left one shifted by f b / Z pixels
// (plus an optional vertical offset that breaks the epipolar geometry).
StereoScene makeSetup(double Z, double b, double dy_px) {
  StereoScene s;
  const cv::Mat left = texture();
  const double d = 400.0 * b / Z;
  cv::Mat right;
  const cv::Mat A = (cv::Mat_<double>(2, 3) << 1, 0, -d, 0, 1, dy_px);
  cv::warpAffine(left, right, A, left.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  cv::buildOpticalFlowPyramid(left, s.pyr0, cv::Size(15, 15), 3, true, cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT, false);
  cv::buildOpticalFlowPyramid(right, s.pyr1, cv::Size(15, 15), 3, true, cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT,
                              false);
  cv::Mat mask = detectionMask(left.size(), {}, 30.0, 20, nullptr);
  PointDetectorParams p;
  s.px0 = detectCorners(left, &mask, 100, p);
  for (const auto& q : s.px0) {
    Vec2 uv;
    s.cam->undistort(Vec2(q.x, q.y), &uv);
    s.uv0.push_back(uv);
  }
  return s;
}

TEST(PointStereo, PlaneDepthIsRecovered) {
  const double b = 0.11;
  for (const double Z : {0.6, 2.0, 6.0}) {
    StereoScene s = makeSetup(Z, b, 0.0);
    const Pose T_C1_C0(Quat::Identity(), Vec3(-b, 0.0, 0.0));
    StereoPointStats st;
    const auto res = matchStereoPoints(s.pyr0, s.pyr1, *s.cam, *s.cam, T_C1_C0, s.px0, s.uv0, nullptr,
                                       StereoPointParams(), &st);
    int ok = 0, visible = 0;
    for (std::size_t i = 0; i < res.size(); ++i) {
      if (s.px0[i].x - 400.0 * b / Z < 10) continue;  // leaves cam1's view
      ++visible;
      if (!res[i].ok) continue;
      ++ok;
      EXPECT_NEAR(1.0 / res[i].inverse_depth, Z, 0.03 * Z);
      EXPECT_NEAR(res[i].px1.x, s.px0[i].x - 400.0 * b / Z, 0.1);
      EXPECT_NEAR(res[i].px1.y, s.px0[i].y, 0.1);
    }
    EXPECT_GE(ok, 0.95 * visible) << "Z " << Z;
    EXPECT_GE(st.matched, ok);
  }
}

TEST(PointStereo, PriorSkipsTheSearch) {
  const double b = 0.11, Z = 1.5;
  StereoScene s = makeSetup(Z, b, 0.0);
  std::vector<cv::Point2f> prior;
  for (const auto& q : s.px0) prior.emplace_back(q.x - float(400.0 * b / Z) + 0.7f, q.y - 0.5f);
  StereoPointStats st;
  const auto res = matchStereoPoints(s.pyr0, s.pyr1, *s.cam, *s.cam, Pose(Quat::Identity(), Vec3(-b, 0, 0)), s.px0,
                                     s.uv0, &prior, StereoPointParams(), &st);
  EXPECT_EQ(st.searched, 0);
  EXPECT_GE(st.matched, static_cast<int>(0.9 * res.size()));
}

TEST(PointStereo, PriorsOnFullResolutionAgreeWithThePlainPath) {
  // Half the points have a prior (0.3 px off, as a last match carried by the left flow is: 0.09 px median on MH_01
  // hall hard), half are searched. On full resolution alone, with the round trip skipped where the KLT ends within
  // 0.5 px of the prior, every point ends where the plain path (all levels, every round trip) puts it.
  const double b = 0.11, Z = 1.5, d = 400.0 * b / Z;
  StereoScene s = makeSetup(Z, b, 0.0);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<cv::Point2f> prior;
  for (std::size_t i = 0; i < s.px0.size(); ++i)
    prior.push_back(i % 2 == 0 ? cv::Point2f(s.px0[i].x - float(d) + 0.3f, s.px0[i].y - 0.1f) : cv::Point2f(nan, nan));
  const Pose T_C1_C0(Quat::Identity(), Vec3(-b, 0, 0));
  StereoPointParams plain, fast;
  fast.prior_levels = 0;
  fast.prior_agree_px = 0.5;
  StereoPointStats st_plain, st_fast;
  const auto a = matchStereoPoints(s.pyr0, s.pyr1, *s.cam, *s.cam, T_C1_C0, s.px0, s.uv0, &prior, plain, &st_plain);
  const auto f = matchStereoPoints(s.pyr0, s.pyr1, *s.cam, *s.cam, T_C1_C0, s.px0, s.uv0, &prior, fast, &st_fast);
  EXPECT_EQ(st_plain.round_trip_skipped, 0);
  int with_prior = 0, same = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (i % 2 != 0) {  // searched: the same calls as the plain path, bit for bit
      EXPECT_EQ(a[i].ok, f[i].ok) << i;
      if (a[i].ok && f[i].ok) {
        EXPECT_EQ(a[i].px1.x, f[i].px1.x) << i;
        EXPECT_EQ(a[i].px1.y, f[i].px1.y) << i;
      }
      continue;
    }
    if (!a[i].ok) continue;
    ++with_prior;
    if (!f[i].ok) continue;
    ++same;
    EXPECT_NEAR(f[i].px1.x, a[i].px1.x, 0.02) << i;
    EXPECT_NEAR(f[i].px1.y, a[i].px1.y, 0.02) << i;
    EXPECT_NEAR(f[i].px1.x, s.px0[i].x - d, 0.1) << i;
  }
  EXPECT_GE(with_prior, 30);
  EXPECT_EQ(same, with_prior);
  EXPECT_GE(st_fast.round_trip_skipped, with_prior * 9 / 10);
}

TEST(PointStereo, PriorsThatDisagreeTakeTheRoundTrip) {
  // A prior 2 px off: the full-resolution KLT still converges (its window is 15 px), but it moves more than 0.5 px
  // from the prior, so every such point takes the round trip, and the matches stay right.
  const double b = 0.11, Z = 2.0, d = 400.0 * b / Z;
  StereoScene s = makeSetup(Z, b, 0.0);
  std::vector<cv::Point2f> prior;
  for (const auto& q : s.px0) prior.emplace_back(q.x - float(d) + 2.0f, q.y);
  StereoPointParams fast;
  fast.prior_levels = 0;
  fast.prior_agree_px = 0.5;
  StereoPointStats st;
  const auto res = matchStereoPoints(s.pyr0, s.pyr1, *s.cam, *s.cam, Pose(Quat::Identity(), Vec3(-b, 0, 0)), s.px0,
                                     s.uv0, &prior, fast, &st);
  EXPECT_EQ(st.round_trip_skipped, 0);
  EXPECT_GE(st.matched, static_cast<int>(0.9 * res.size()));
  for (std::size_t i = 0; i < res.size(); ++i) {
    if (!res[i].ok) continue;
    EXPECT_NEAR(res[i].px1.x, s.px0[i].x - d, 0.1) << i;
  }
}

// The plain ZNCC the kernel replaced: OpenCV's sub-pixel patches (single precision) and statistics.
double plainZncc(const cv::Mat& img0, const cv::Point2f& c0, const cv::Mat& img1, const cv::Point2f& c1, int h) {
  const cv::Size size(2 * h + 1, 2 * h + 1);
  cv::Mat a, b;
  cv::getRectSubPix(img0, size, c0, a, CV_32F);
  cv::getRectSubPix(img1, size, c1, b, CV_32F);
  cv::Scalar ma, sa, mb, sb;
  cv::meanStdDev(a, ma, sa);
  cv::meanStdDev(b, mb, sb);
  if (sa[0] < 1e-3 || sb[0] < 1e-3) return -1.0;
  a -= ma[0];
  b -= mb[0];
  return a.dot(b) / (sa[0] * sb[0] * static_cast<double>(a.total()));
}

// The same in double precision from the pixels: bilinear weights of the centre's fraction, border replicated.
double doubleZncc(const cv::Mat& img0, const cv::Point2f& c0, const cv::Mat& img1, const cv::Point2f& c1, int h) {
  const auto patch = [h](const cv::Mat& img, const cv::Point2f& c) {
    std::vector<double> v;
    const float x0 = c.x - static_cast<float>(h), y0 = c.y - static_cast<float>(h);
    const int ix = cvFloor(x0), iy = cvFloor(y0);
    const double a = x0 - static_cast<float>(ix), b = y0 - static_cast<float>(iy);
    const auto at = [&](int x, int y) -> double {
      return img.at<unsigned char>(std::clamp(y, 0, img.rows - 1), std::clamp(x, 0, img.cols - 1));
    };
    for (int y = 0; y <= 2 * h; ++y)
      for (int x = 0; x <= 2 * h; ++x)
        v.push_back((1 - a) * (1 - b) * at(ix + x, iy + y) + a * (1 - b) * at(ix + x + 1, iy + y) +
                    (1 - a) * b * at(ix + x, iy + y + 1) + a * b * at(ix + x + 1, iy + y + 1));
    return v;
  };
  const std::vector<double> a = patch(img0, c0), b = patch(img1, c1);
  const double n = static_cast<double>(a.size());
  double ma = 0, mb = 0;
  for (std::size_t k = 0; k < a.size(); ++k) ma += a[k] / n, mb += b[k] / n;
  double saa = 0, sbb = 0, sab = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    saa += (a[k] - ma) * (a[k] - ma);
    sbb += (b[k] - mb) * (b[k] - mb);
    sab += (a[k] - ma) * (b[k] - mb);
  }
  if (std::sqrt(saa / n) < 1e-3 || std::sqrt(sbb / n) < 1e-3) return -1.0;
  return sab / std::sqrt(saa * sbb);
}

TEST(PointStereo, SubpixelZnccAgreesWithThePlainVersions) {
  // Centres inside, across the border (replicated pixels) and exactly on pixels; patches of several sizes.
  const cv::Mat img0 = texture();
  cv::Mat img1;
  cv::GaussianBlur(img0, img1, cv::Size(0, 0), 0.8);
  cv::RNG rng(3);
  int compared = 0;
  for (int i = 0; i < 400; ++i) {
    const int h = 1 + i % 6;
    const cv::Point2f c0(rng.uniform(-3.f, 643.f), rng.uniform(-3.f, 483.f));
    const cv::Point2f c1 = i % 5 == 0 ? cv::Point2f(std::round(c0.x), std::round(c0.y))
                                      : c0 + cv::Point2f(rng.uniform(-2.f, 2.f), rng.uniform(-2.f, 2.f));
    const double z = subpixelZncc(img0, c0, img1, c1, h);
    EXPECT_NEAR(z, doubleZncc(img0, c0, img1, c1, h), 1e-9) << i;
    // OpenCV samples in single precision, and gives the right-hand neighbour a weight of at least 1e-4 (so a patch
    // on whole pixels is not exactly those pixels): the same to about 1e-4 of the ZNCC's range.
    EXPECT_NEAR(z, plainZncc(img0, c0, img1, c1, h), 1e-4) << i;
    ++compared;
  }
  EXPECT_EQ(compared, 400);
  const cv::Mat flat(480, 640, CV_8U, cv::Scalar(90));
  EXPECT_EQ(subpixelZncc(flat, cv::Point2f(100.3f, 50.5f), img1, cv::Point2f(100.f, 50.f), 4), -1.0);
  EXPECT_THROW(subpixelZncc(img0, cv::Point2f(0, 0), img1, cv::Point2f(0, 0), 17), UsageError);
}

TEST(PointStereo, OffEpipolarImageIsRejected) {
  // The right image is also shifted 6 px down: KLT finds the texture, the epipolar check refuses it. A few smooth
  // patches still find a look-alike on the epipolar line (the texture's low-frequency part): at most 10%.
  const double b = 0.11, Z = 2.0;
  StereoScene s = makeSetup(Z, b, 6.0);
  StereoPointStats st;
  matchStereoPoints(s.pyr0, s.pyr1, *s.cam, *s.cam, Pose(Quat::Identity(), Vec3(-b, 0, 0)), s.px0, s.uv0, nullptr,
                    StereoPointParams(), &st);
  EXPECT_LE(st.matched, static_cast<int>(s.px0.size()) / 10);
  std::printf("[points] off-epipolar: %d matched, %d epipolar-rejected, %d verify-rejected\n", st.matched,
              st.epipolar_rejected, st.verify_rejected);
}

}  // namespace
}  // namespace linnet
