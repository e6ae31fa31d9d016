// fastCorners: cv::FAST's keypoints (9-16, non-maximum suppression) bit for bit, on images of every kind of texture
// and size, at every kind of threshold; the fallbacks and bad input.
#include "linnet/features/fast_corners.h"

#include <vector>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"

namespace linnet {
namespace {

// Noise smoothed by `blur` (0: raw), plus saturated blocks and lines, so that corners, plateaus and the 0 / 255 ends
// (where v + t and v - t saturate) all occur.
cv::Mat scene(int rows, int cols, int seed, double blur) {
  cv::Mat img(rows, cols, CV_8UC1);
  cv::RNG rng(static_cast<std::uint64_t>(seed));
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  if (blur > 0.0) {
    cv::GaussianBlur(img, img, cv::Size(0, 0), blur);
    cv::normalize(img, img, 0, 255, cv::NORM_MINMAX);
  }
  for (int k = 0; k < 6; ++k) {
    const cv::Point a(rng.uniform(0, cols), rng.uniform(0, rows)), b(rng.uniform(0, cols), rng.uniform(0, rows));
    cv::rectangle(img, a, a + cv::Point(rng.uniform(3, 40), rng.uniform(3, 40)), cv::Scalar(k % 2 ? 255 : 0),
                  cv::FILLED);
    cv::line(img, a, b, cv::Scalar(rng.uniform(0, 256)), 1 + k % 3);
  }
  return img;
}

void expectSameAsOpenCv(const cv::Mat& img, int threshold, bool simd, const std::string& what) {
  std::vector<cv::KeyPoint> ours, theirs;
  fastCorners(img, threshold, &ours, simd);
  cv::FAST(img, theirs, threshold, true, cv::FastFeatureDetector::TYPE_9_16);
  ASSERT_EQ(ours.size(), theirs.size()) << what;
  for (std::size_t i = 0; i < ours.size(); ++i) {
    ASSERT_EQ(ours[i].pt, theirs[i].pt) << what << ", keypoint " << i;
    ASSERT_EQ(ours[i].response, theirs[i].response) << what << ", keypoint " << i;
    ASSERT_EQ(ours[i].size, theirs[i].size) << what;
    ASSERT_EQ(ours[i].angle, theirs[i].angle) << what;
    ASSERT_EQ(ours[i].octave, theirs[i].octave) << what;
    ASSERT_EQ(ours[i].class_id, theirs[i].class_id) << what;
  }
}

TEST(FastCorners, EqualOpenCvBitForBit) {
  int seed = 0;
  for (const cv::Size size : {cv::Size(752, 480), cv::Size(38, 7), cv::Size(39, 8), cv::Size(70, 41),
                              cv::Size(101, 37), cv::Size(64, 64), cv::Size(200, 9)})
    for (double blur : {0.0, 0.8, 2.0}) {
      const cv::Mat img = scene(size.height, size.width, ++seed, blur);
      for (int threshold : {0, 1, 5, 10, 20, 40, 100, 254, 255})
        expectSameAsOpenCv(img, threshold, true,
                           std::to_string(size.width) + " x " + std::to_string(size.height) + ", blur " +
                               std::to_string(blur) + ", threshold " + std::to_string(threshold));
    }
}

TEST(FastCorners, FindsCornersOnRealisticImages) {
  // The test above must not pass on images without corners: the hard replays' kind of image has thousands.
  std::vector<cv::KeyPoint> kps;
  fastCorners(scene(480, 752, 99, 0.8), 20, &kps);
  EXPECT_GT(kps.size(), 1000u);
}

TEST(FastCorners, ImageViewsWithARowStep) {
  const cv::Mat big = scene(300, 400, 7, 0.8);
  for (const cv::Rect roi : {cv::Rect(5, 3, 250, 200), cv::Rect(0, 0, 399, 300), cv::Rect(17, 11, 40, 30)})
    for (int threshold : {5, 20})
      expectSameAsOpenCv(big(roi), threshold, true, "view " + std::to_string(roi.width) + " x " +
                                                        std::to_string(roi.height) + ", threshold " +
                                                        std::to_string(threshold));
}

TEST(FastCorners, NarrowImagesAndThePlainPathAreOpenCvs) {
  for (const cv::Size size : {cv::Size(37, 50), cv::Size(60, 6), cv::Size(7, 7), cv::Size(1, 1)})
    expectSameAsOpenCv(scene(size.height, size.width, 3, 0.0), 10, true, "small image");
  expectSameAsOpenCv(scene(480, 752, 5, 0.8), 20, false, "simd off");
  std::vector<cv::KeyPoint> kps{cv::KeyPoint(1.f, 2.f, 3.f)};
  fastCorners(cv::Mat(), 20, &kps);
  EXPECT_TRUE(kps.empty());
}

TEST(FastCorners, RejectsOtherImageTypesAndThresholds) {
  std::vector<cv::KeyPoint> kps;
  EXPECT_THROW(fastCorners(cv::Mat(100, 100, CV_8UC3, cv::Scalar::all(0)), 20, &kps), UsageError);
  EXPECT_THROW(fastCorners(cv::Mat(100, 100, CV_16UC1, cv::Scalar(0)), 20, &kps), UsageError);
  EXPECT_THROW(fastCorners(cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)), 256, &kps), UsageError);
  EXPECT_THROW(fastCorners(cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)), -1, &kps), UsageError);
}

}  // namespace
}  // namespace linnet
