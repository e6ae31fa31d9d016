// LBD descriptor: matching by Hamming distance alone under image shift, rotation and brightness change.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <numbers>
#include <random>

#include <opencv2/imgproc.hpp>

#include "features/test_line_scene.h"
#include "linnet/core/error.h"
#include "linnet/features/line_detector.h"
#include "linnet/features/line_lbd.h"
#include "linnet/features/line_matching.h"

namespace linnet {
namespace {

struct Described {
  std::vector<LineSegment> segs;
  std::vector<LbdDescriptor> desc;
};

Described describeImage(const cv::Mat& img) {
  LineDetectorOptions opt;
  opt.max_segments = 80;
  LineDetector det(opt);
  Described d;
  det.detect(img, &d.segs);
  computeLbd(img, LbdOptions{}, d.segs, &d.desc);
  return d;
}

// Matches by descriptor with only the tracker's weakest gate (direction change below 15 degrees; no position
// prior); returns (correct, total) judged with the known warp.
std::pair<int, int> matchAndScore(const Described& a, const Described& b, const cv::Matx23d& warp) {
  std::vector<LineMatchCandidate> cands;
  for (int i = 0; i < static_cast<int>(a.segs.size()); ++i)
    for (int j = 0; j < static_cast<int>(b.segs.size()); ++j)
      if (a.segs[i].direction().dot(b.segs[j].direction()) > std::cos(15.0 * std::numbers::pi / 180.0))
        cands.push_back({i, j, hammingDistance(a.desc[i], b.desc[j])});
  std::vector<int> match;
  selectMutualBest(static_cast<int>(a.segs.size()), static_cast<int>(b.segs.size()), cands, 80, 0.9, &match);
  int correct = 0, total = 0;
  auto apply = [&](const Vec2& p) {
    return Vec2(warp(0, 0) * p.x() + warp(0, 1) * p.y() + warp(0, 2), warp(1, 0) * p.x() + warp(1, 1) * p.y() + warp(1, 2));
  };
  for (int i = 0; i < static_cast<int>(match.size()); ++i) {
    if (match[i] < 0) continue;
    ++total;
    const LineSegment& s = b.segs[match[i]];
    const Vec2 m = apply(a.segs[i].midpoint());
    const Vec2 d = (apply(a.segs[i].e) - apply(a.segs[i].s)).normalized();
    const bool same_line = std::abs((m - s.s).dot(s.normal())) < 3.0 && d.dot(s.direction()) > 0.98;
    const double t = (m - s.s).dot(s.direction());
    const bool ok = same_line && t > -0.5 * s.length() && t < 1.5 * s.length();
    correct += ok;
    if (!ok)
      std::printf("  wrong: %.0f,%.0f->%.0f,%.0f (warped mid %.0f,%.0f) matched %.0f,%.0f->%.0f,%.0f dist %d\n",
                  a.segs[i].s.x(), a.segs[i].s.y(), a.segs[i].e.x(), a.segs[i].e.y(), m.x(), m.y(), s.s.x(), s.s.y(),
                  s.e.x(), s.e.y(), hammingDistance(a.desc[i], b.desc[match[i]]));
  }
  return {correct, total};
}

class LbdInvariance : public ::testing::Test {
 protected:
  void SetUp() override {
    const PinholeCamera cam(752, 480, 450.0, 450.0, 375.5, 239.5);
    base_ = testing::renderScene(testing::makeScene(11, 18), cam, Pose(), 1.5, 2);
    ref_ = describeImage(base_);
    ASSERT_GT(ref_.segs.size(), 20u);
  }
  void check(const cv::Mat& img, const cv::Matx23d& warp, double min_precision, double min_fraction) {
    const Described other = describeImage(img);
    const auto [correct, total] = matchAndScore(ref_, other, warp);
    const double precision = total > 0 ? double(correct) / total : 0.0;
    std::printf("  descriptor matches: %d, correct %d (precision %.3f) of %zu segments\n", total, correct,
                precision, ref_.segs.size());
    EXPECT_GE(precision, min_precision);
    EXPECT_GE(total, static_cast<int>(min_fraction * ref_.segs.size()));
  }
  cv::Mat base_;
  Described ref_;
};

TEST_F(LbdInvariance, Shift) {
  const cv::Matx23d warp(1, 0, 13.3, 0, 1, -7.6);
  cv::Mat img;
  cv::warpAffine(base_, img, warp, base_.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  check(img, warp, 0.95, 0.5);
}

TEST_F(LbdInvariance, Rotation) {
  const cv::Matx23d warp = cv::getRotationMatrix2D(cv::Point2f(375.5f, 239.5f), 10.0, 1.0);
  cv::Mat img;
  cv::warpAffine(base_, img, warp, base_.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  check(img, warp, 0.9, 0.4);
}

TEST_F(LbdInvariance, Brightness) {
  cv::Mat img;
  base_.convertTo(img, CV_8UC1, 0.6, 30.0);
  check(img, cv::Matx23d(1, 0, 0, 0, 1, 0), 0.95, 0.5);
}

TEST(Lbd, DescriptorBasics) {
  cv::Mat img(100, 100, CV_8UC1, cv::Scalar(0));
  cv::rectangle(img, cv::Point(0, 50), cv::Point(99, 99), cv::Scalar(200), cv::FILLED);
  LineSegment s;
  s.s = Vec2(10, 49.5);
  s.e = Vec2(90, 49.5);
  const auto f = computeLbdFloat(img, LbdOptions{}, s);
  double norm = 0.0;
  for (float v : f) norm += v * v;
  EXPECT_NEAR(norm, 1.0, 1e-4);
  // A flat image has no gradient: a zero descriptor, no NaN.
  const auto z = computeLbdFloat(cv::Mat(100, 100, CV_8UC1, cv::Scalar(9)), LbdOptions{}, s);
  for (float v : z) EXPECT_EQ(v, 0.0f);
  // A segment partly outside the image is still described (border replicated).
  LineSegment out = s;
  out.e = Vec2(150, 49.5);
  const auto g = computeLbdFloat(img, LbdOptions{}, out);
  for (float v : g) EXPECT_TRUE(std::isfinite(v));
  EXPECT_EQ(hammingDistance(binarizeLbd(f), binarizeLbd(f)), 0);
  std::vector<LbdDescriptor> d;
  EXPECT_THROW(computeLbd(cv::Mat(5, 5, CV_32F), LbdOptions{}, {s}, &d), UsageError);
}

TEST(Lbd, FastKernelEqualsThePlainOneBitForBit) {
  // A textured image (noise, gradients and edges) and segments of every length and direction, inside, crossing and
  // outside the border, with the sample counts the options allow around the SIMD widths.
  cv::Mat img(240, 320, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(img, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  cv::rectangle(img, cv::Point(60, 40), cv::Point(200, 150), cv::Scalar(250), 3);
  std::mt19937 gen(3);
  std::uniform_real_distribution<double> x(-60.0, 380.0), y(-60.0, 300.0), len(0.5, 400.0), ang(-M_PI, M_PI);
  int compared = 0, nonzero = 0;
  for (int max_samples : {4, 15, 16, 17, 33, 1024}) {
    LbdOptions o;
    o.max_samples = max_samples;
    for (int k = 0; k < 400; ++k) {
      LineSegment s;
      s.s = Vec2(x(gen), y(gen));
      const double a = ang(gen), l = len(gen);
      s.e = s.s + l * Vec2(std::cos(a), std::sin(a));
      const auto fast = computeLbdFloat(img, o, s), plain = computeLbdFloatPlain(img, o, s);
      ASSERT_EQ(0, std::memcmp(fast.data(), plain.data(), sizeof(float) * fast.size()))
          << "max_samples " << max_samples << ", segment " << s.s.transpose() << " -> " << s.e.transpose();
      ++compared;
      nonzero += fast[0] != 0.0f || fast[4] != 0.0f;
    }
  }
  EXPECT_EQ(compared, 2400);
  EXPECT_GT(nonzero, 1200);  // most segments are described (not the zero descriptor of a flat or tiny region)
}

}  // namespace
}  // namespace linnet
