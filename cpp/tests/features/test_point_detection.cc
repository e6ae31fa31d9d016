// Corner detection: quota, minimum distance, mask, spread over the grid, determinism, degenerate images.
#include <random>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"
#include "linnet/features/point_detection.h"

namespace linnet {
namespace {

cv::Mat texture(unsigned seed) {
  cv::Mat a(480, 640, CV_32F);
  cv::RNG rng(seed);
  rng.fill(a, cv::RNG::UNIFORM, 0.0, 255.0);
  cv::GaussianBlur(a, a, cv::Size(0, 0), 2.0);
  cv::normalize(a, a, 0, 255, cv::NORM_MINMAX);
  cv::Mat img;
  a.convertTo(img, CV_8U);
  return img;
}

double minPairDistance(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b, bool same) {
  double best = 1e9;
  for (std::size_t i = 0; i < a.size(); ++i)
    for (std::size_t j = same ? i + 1 : 0; j < b.size(); ++j) best = std::min(best, double(cv::norm(a[i] - b[j])));
  return best;
}

TEST(PointDetection, QuotaDistanceMaskAndSpread) {
  const cv::Mat img = texture(1);
  for (const char* det : {"fast", "shi_tomasi"}) {
    PointDetectorParams p;
    p.detector = det;
    p.min_distance_px = 25.0;
    const std::vector<cv::Point2f> existing{{100.f, 100.f}, {300.f, 200.f}, {500.f, 400.f}};
    cv::Mat mask = detectionMask(img.size(), existing, p.min_distance_px, p.border_px, nullptr);
    const auto pts = detectCorners(img, &mask, 120, p);
    EXPECT_EQ(pts.size(), 120u) << det;
    EXPECT_GE(minPairDistance(pts, pts, true), p.min_distance_px - 1.0) << det;
    EXPECT_GE(minPairDistance(pts, existing, false), p.min_distance_px - 1.0) << det;
    std::vector<int> cells(static_cast<std::size_t>(p.grid_cols * p.grid_rows), 0);
    for (const auto& q : pts) {
      EXPECT_GE(q.x, p.border_px);
      EXPECT_GE(q.y, p.border_px);
      EXPECT_LT(q.x, img.cols - p.border_px);
      EXPECT_LT(q.y, img.rows - p.border_px);
      ++cells[static_cast<std::size_t>(int(q.y / (480.0 / p.grid_rows)) * p.grid_cols + int(q.x / (640.0 / p.grid_cols)))];
    }
    EXPECT_GE(std::count_if(cells.begin(), cells.end(), [](int c) { return c > 0; }), 40) << det;  // of 48
    cv::Mat mask2 = detectionMask(img.size(), existing, p.min_distance_px, p.border_px, nullptr);
    EXPECT_EQ(pts, detectCorners(img, &mask2, 120, p)) << det;  // deterministic
  }
}

TEST(PointDetection, FreeRegionSearchEqualsTheWholeImageSearch) {
  // FAST runs only on the free part of each grid cell (its bounding box plus FAST's margin). With one grid cell and
  // one threshold (no cascade), the plain version is a whole-image FAST, the corners on free mask pixels taken
  // strongest first with their exclusion discs: the same corners, in the same order.
  const cv::Mat img = texture(3);
  cv::Mat blocked(img.size(), CV_8UC1, cv::Scalar(0));
  cv::rectangle(blocked, cv::Rect(60, 50, 120, 90), cv::Scalar(255), cv::FILLED);  // two free regions, and a
  cv::circle(blocked, cv::Point(450, 330), 70, cv::Scalar(255), cv::FILLED);       // third at the image border
  cv::rectangle(blocked, cv::Rect(600, 0, 40, 480), cv::Scalar(255), cv::FILLED);
  PointDetectorParams p;
  p.fast_threshold = 5;  // halving it would go below 5: one round
  p.grid_cols = p.grid_rows = 1;
  p.min_distance_px = 2.0;  // nearly every candidate taken, those at the free regions' edges too
  const int max_new = 100000;
  cv::Mat mask = blocked.clone();
  const std::vector<cv::Point2f> got = detectCorners(img, &mask, max_new, p);

  std::vector<cv::KeyPoint> kps;
  cv::FAST(img, kps, p.fast_threshold, true, cv::FastFeatureDetector::TYPE_9_16);
  std::stable_sort(kps.begin(), kps.end(), [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
    if (a.response != b.response) return a.response > b.response;
    if (a.pt.y != b.pt.y) return a.pt.y < b.pt.y;
    return a.pt.x < b.pt.x;
  });
  cv::Mat ref_mask = blocked.clone();
  std::vector<cv::Point2f> want;
  for (const cv::KeyPoint& k : kps) {
    if (static_cast<int>(want.size()) >= max_new) break;
    const cv::Point c(cvRound(k.pt.x), cvRound(k.pt.y));
    if (!ref_mask.at<unsigned char>(c)) continue;
    want.push_back(k.pt);
    cv::circle(ref_mask, c, 2, cv::Scalar(0), cv::FILLED);
  }
  ASSERT_GT(want.size(), 200u);
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i], want[i]) << i;
}

TEST(PointDetection, FirstRoundHandsOnTheWholeImagesCorners) {
  const cv::Mat img = texture(3);
  PointDetectorParams p;
  const std::vector<cv::Point2f> existing{{100.f, 100.f}, {300.f, 200.f}};
  cv::Mat mask = detectionMask(img.size(), existing, p.min_distance_px, p.border_px, nullptr);
  FastCorners first;
  const auto pts = detectCorners(img, &mask, 120, p, &first);
  std::vector<cv::KeyPoint> plain;
  cv::FAST(img, plain, p.fast_threshold, true);
  EXPECT_EQ(first.threshold, p.fast_threshold);
  ASSERT_EQ(first.keypoints.size(), plain.size());
  for (std::size_t i = 0; i < plain.size(); ++i) {
    EXPECT_EQ(first.keypoints[i].pt, plain[i].pt) << i;
    EXPECT_EQ(first.keypoints[i].response, plain[i].response) << i;
  }
  // Handing them on changes nothing of the detection.
  cv::Mat mask2 = detectionMask(img.size(), existing, p.min_distance_px, p.border_px, nullptr);
  EXPECT_EQ(pts, detectCorners(img, &mask2, 120, p));
  // Shi-Tomasi hands on nothing.
  p.detector = "shi_tomasi";
  FastCorners none;
  cv::Mat mask3 = detectionMask(img.size(), existing, p.min_distance_px, p.border_px, nullptr);
  detectCorners(img, &mask3, 120, p, &none);
  EXPECT_LT(none.threshold, 0);
  EXPECT_TRUE(none.keypoints.empty());
}

TEST(PointDetection, CrowdedTracksAreFlagged) {
  std::vector<unsigned char> keep;
  const std::vector<cv::Point2f> pts{{100.f, 100.f}, {110.f, 100.f}, {200.f, 100.f}, {100.f, 125.f}};
  detectionMask(cv::Size(640, 480), pts, 30.0, 5, &keep);
  EXPECT_EQ(keep, (std::vector<unsigned char>{1, 0, 1, 0}));
}

TEST(PointDetection, MaskEqualsThePlainDrawingBitForBit) {
  // The mask is the border rectangle without the kept points' discs, computed from the discs drawn once; the plain
  // version draws each disc into the mask as well. Points outside the image, crowded ones and all borders.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> x(-40.f, 700.f), y(-40.f, 520.f);
  const cv::Size size(640, 480);
  for (int trial = 0; trial < 12; ++trial) {
    std::vector<cv::Point2f> pts(static_cast<std::size_t>(20 * trial));
    for (cv::Point2f& p : pts) p = {x(rng), y(rng)};
    for (const int border : {0, 1, 8, 239, 240, 400}) {
      std::vector<unsigned char> keep;
      const cv::Mat mask = detectionMask(size, pts, 30.0, border, &keep);
      cv::Mat plain(size, CV_8UC1, cv::Scalar(0)), occupied(size, CV_8UC1, cv::Scalar(0));
      if (size.width > 2 * border && size.height > 2 * border)
        plain(cv::Rect(border, border, size.width - 2 * border, size.height - 2 * border)).setTo(255);
      std::vector<unsigned char> plain_keep(pts.size(), 1);
      for (std::size_t i = 0; i < pts.size(); ++i) {
        const cv::Point c(cvRound(pts[i].x), cvRound(pts[i].y));
        if (cv::Rect(0, 0, size.width, size.height).contains(c) && occupied.at<unsigned char>(c)) {
          plain_keep[i] = 0;
          continue;
        }
        cv::circle(occupied, c, 30, cv::Scalar(255), cv::FILLED);
        cv::circle(plain, c, 30, cv::Scalar(0), cv::FILLED);
      }
      ASSERT_EQ(mask.size(), size);
      ASSERT_EQ(mask.type(), CV_8UC1);
      EXPECT_EQ(cv::countNonZero(mask != plain), 0) << "trial " << trial << ", border " << border;
      EXPECT_EQ(keep, plain_keep);
    }
  }
}

TEST(PointDetection, FlatImagesGiveNothing) {
  for (const int v : {0, 255, 77}) {
    const cv::Mat img(480, 640, CV_8UC1, cv::Scalar(v));
    cv::Mat mask = detectionMask(img.size(), {}, 30.0, 8, nullptr);
    PointDetectorParams p;
    EXPECT_TRUE(detectCorners(img, &mask, 150, p).empty());
    p.detector = "shi_tomasi";
    EXPECT_TRUE(detectCorners(img, &mask, 150, p).empty());
  }
  cv::Mat color(480, 640, CV_8UC3), mask(480, 640, CV_8UC1);
  EXPECT_THROW(detectCorners(color, &mask, 10, PointDetectorParams()), UsageError);
}

}  // namespace
}  // namespace linnet
