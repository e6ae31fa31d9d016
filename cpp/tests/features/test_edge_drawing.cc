// Edge Drawing chains and EDLines pieces on images with known edges.
#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "linnet/features/edge_drawing.h"

namespace linnet {
namespace {

// Area-sampled (4x4 per pixel) image of a predicate, then a light blur: edges sit exactly on the predicate's border.
template <class Inside>
cv::Mat render(Inside inside, int dark, int bright) {
  cv::Mat img(480, 752, CV_8UC1);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      int n = 0;
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx) n += inside(x - 0.5 + (sx + 0.5) / 4.0, y - 0.5 + (sy + 0.5) / 4.0);
      img.at<std::uint8_t>(y, x) = cv::saturate_cast<std::uint8_t>(dark + (bright - dark) * n / 16.0);
    }
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.7);
  return img;
}

// A square rotated by `angle` around (cx, cy) with half-side h.
struct Square {
  double cx = 380.0, cy = 240.0, h = 120.0, angle = 0.3;
  bool operator()(double x, double y) const {
    const double c = std::cos(angle), s = std::sin(angle);
    const double u = c * (x - cx) + s * (y - cy), v = -s * (x - cx) + c * (y - cy);
    return std::abs(u) < h && std::abs(v) < h;
  }
  // Distance of (x, y) from the nearest side's line.
  double sideDistance(double x, double y) const {
    const double c = std::cos(angle), s = std::sin(angle);
    const double u = c * (x - cx) + s * (y - cy), v = -s * (x - cx) + c * (y - cy);
    return std::min(std::abs(std::abs(u) - h), std::abs(std::abs(v) - h));
  }
};

TEST(EdgeDrawing, FindsTheFourSidesOfARotatedSquare) {
  const Square sq;
  const cv::Mat img = render(sq, 50, 180);
  EdgeDrawing ed{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines;
  ed.detect(img, &lines);
  double long_total = 0.0;
  int long_count = 0;
  for (const cv::Vec4f& l : lines) {
    EXPECT_LT(sq.sideDistance(l[0], l[1]), 1.0) << l;
    EXPECT_LT(sq.sideDistance(l[2], l[3]), 1.0) << l;
    const double len = std::hypot(l[2] - l[0], l[3] - l[1]);
    if (len > 100.0) {
      long_total += len;
      ++long_count;
    }
  }
  // Each side (240 px) comes out whole or in very few pieces; the corners cost a few pixels each.
  EXPECT_GE(long_count, 4);
  EXPECT_LE(long_count, 6);
  EXPECT_GT(long_total, 0.9 * 4 * 2 * sq.h);
}

TEST(EdgeDrawing, ChainsAreConnectedAndDisjoint) {
  const Square sq;
  const cv::Mat img = render([&](double x, double y) { return sq(x, y) || std::hypot(x - 120, y - 120) < 60; }, 40, 200);
  EdgeDrawing ed{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines;
  ed.detect(img, &lines);
  ASSERT_FALSE(ed.chains().empty());
  std::set<std::pair<int, int>> seen;
  for (const std::vector<cv::Point>& chain : ed.chains()) {
    for (std::size_t k = 0; k < chain.size(); ++k) {
      EXPECT_TRUE(seen.insert({chain[k].x, chain[k].y}).second) << "pixel in two chains: " << chain[k];
      if (k > 0) {
        const cv::Point d = chain[k] - chain[k - 1];
        EXPECT_LE(std::max(std::abs(d.x), std::abs(d.y)), 1) << "gap in a chain at " << chain[k];
      }
    }
  }
}

TEST(EdgeDrawing, ACircleGivesOnlyShortChords) {
  const double r = 100.0;
  const cv::Mat img = render([&](double x, double y) { return std::hypot(x - 376, y - 240) < r; }, 60, 190);
  EdgeDrawingOptions opt;
  EdgeDrawing ed(opt);
  std::vector<cv::Vec4f> lines;
  ed.detect(img, &lines);
  EXPECT_FALSE(lines.empty());
  // A chord whose sagitta stays within the fit tolerance: 2 sqrt(2 r tol), with a pixel of quantisation slack.
  const double longest = 2.0 * std::sqrt(2.0 * r * (opt.fit_error_px + 1.0));
  for (const cv::Vec4f& l : lines) EXPECT_LT(std::hypot(l[2] - l[0], l[3] - l[1]), longest) << l;
}

TEST(EdgeDrawing, FlatNoiseAndTinyImages) {
  EdgeDrawing ed{EdgeDrawingOptions{}};
  std::vector<cv::Vec4f> lines;
  ed.detect(cv::Mat(480, 752, CV_8UC1, cv::Scalar(128)), &lines);
  EXPECT_TRUE(lines.empty());
  ed.detect(cv::Mat(5, 5, CV_8UC1, cv::Scalar(0)), &lines);
  EXPECT_TRUE(lines.empty());
  cv::Mat noise(480, 752, CV_8UC1);
  cv::RNG rng(3);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  ed.detect(noise, &lines);  // must terminate; pure noise gives few and short pieces
  for (const cv::Vec4f& l : lines) EXPECT_LT(std::hypot(l[2] - l[0], l[3] - l[1]), 60.0);
}

}  // namespace
}  // namespace linnet
