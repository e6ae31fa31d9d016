// pyramidDown and buildPyramid against cv::pyrDown and cv::buildOpticalFlowPyramid: the same bytes.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "linnet/core/error.h"
#include "linnet/features/image_pyramid.h"

namespace linnet {
namespace {

cv::Mat randomImage(int rows, int cols, std::uint64_t seed) {
  cv::Mat m(rows, cols, CV_8UC1);
  cv::RNG rng(seed);
  rng.fill(m, cv::RNG::UNIFORM, 0, 256);
  return m;
}

// The whole allocation behind a view (padding included).
cv::Mat whole(const cv::Mat& view) {
  cv::Size size;
  cv::Point ofs;
  view.locateROI(size, ofs);
  return cv::Mat(size, view.type(), const_cast<uchar*>(view.datastart), view.step[0]);
}

TEST(ImagePyramid, PyramidDownEqualsOpenCv) {
  std::uint64_t seed = 1;
  for (const int rows : {1, 2, 3, 4, 5, 7, 30, 61, 480})
    for (const int cols : {1, 2, 3, 4, 5, 6, 9, 16, 31, 33, 64, 101, 752}) {
      const cv::Mat src = randomImage(rows, cols, seed++);
      cv::Mat ours, ref;
      pyramidDown(src, ours);
      cv::pyrDown(src, ref);
      ASSERT_EQ(ours.size(), ref.size()) << rows << " x " << cols;
      ASSERT_EQ(cv::norm(ours, ref, cv::NORM_INF), 0.0) << rows << " x " << cols;
    }
}

TEST(ImagePyramid, BuildPyramidEqualsOpenCvPaddingIncluded) {
  std::uint64_t seed = 100;
  for (const cv::Size image : {cv::Size(752, 480), cv::Size(640, 481), cv::Size(101, 67), cv::Size(40, 33)})
    for (const int window : {15, 21})
      for (const int levels : {0, 1, 3, 6}) {
        const cv::Mat img = randomImage(image.height, image.width, seed++);
        std::vector<cv::Mat> ours, ref;
        // Twice into the same vector: the second build reuses the buffers.
        for (int pass = 0; pass < 2; ++pass) {
          const int n = buildPyramid(img, cv::Size(window, window), levels, &ours);
          const int m = cv::buildOpticalFlowPyramid(img, ref, cv::Size(window, window), levels, false,
                                                    cv::BORDER_REFLECT_101, cv::BORDER_CONSTANT, false);
          ASSERT_EQ(n, m);
          ASSERT_EQ(ours.size(), ref.size());
          for (std::size_t l = 0; l < ref.size(); ++l) {
            ASSERT_EQ(ours[l].size(), ref[l].size());
            const cv::Mat a = whole(ours[l]), b = whole(ref[l]);
            ASSERT_EQ(a.size(), b.size());
            ASSERT_EQ(cv::norm(a, b, cv::NORM_INF), 0.0) << image << " window " << window << " level " << l;
          }
        }
      }
}

TEST(ImagePyramid, LayoutWithAndWithoutDerivativeImages) {
  const cv::Mat img = randomImage(240, 320, 7);
  for (const bool derivatives : {false, true}) {
    std::vector<cv::Mat> pyr;
    cv::buildOpticalFlowPyramid(img, pyr, cv::Size(15, 15), 3, derivatives);
    const PyramidLayout l = pyramidLayout(pyr);
    EXPECT_EQ(l.levels, 4);
    EXPECT_EQ(l.step, derivatives ? 2 : 1);
    EXPECT_EQ(pyramidLevel(pyr, 2).size(), cv::Size(80, 60));
    EXPECT_EQ(pyramidLevel(pyr, 9).size(), cv::Size(40, 30));  // the coarsest level
    EXPECT_EQ(pyramidLevel(pyr, 0).type(), CV_8UC1);
  }
  EXPECT_THROW(pyramidLevel(std::vector<cv::Mat>(), 0), UsageError);
}

TEST(ImagePyramid, RejectsWhatItCannotBuild) {
  std::vector<cv::Mat> pyr;
  EXPECT_THROW(buildPyramid(cv::Mat(), cv::Size(15, 15), 3, &pyr), UsageError);
  EXPECT_THROW(buildPyramid(cv::Mat(20, 20, CV_8UC3), cv::Size(15, 15), 3, &pyr), UsageError);
  EXPECT_THROW(buildPyramid(cv::Mat(20, 20, CV_8UC1), cv::Size(2, 2), 3, &pyr), UsageError);
  cv::Mat out;
  EXPECT_THROW(pyramidDown(cv::Mat(20, 20, CV_16UC1), out), UsageError);
}

}  // namespace
}  // namespace linnet
