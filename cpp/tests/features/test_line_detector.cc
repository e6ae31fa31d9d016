// Line detection: accuracy on a synthetic scene, orientation convention, degenerate images, option errors.
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>

#include "features/test_line_scene.h"
#include "linnet/core/error.h"
#include "linnet/features/line_detector.h"

namespace linnet {
namespace {

PinholeCamera testCamera() { return PinholeCamera(752, 480, 450.0, 450.0, 375.5, 239.5); }

class DetectorTest : public ::testing::TestWithParam<std::string> {};

TEST_P(DetectorTest, FindsSceneEdgesWithinTwoPixels) {
  const PinholeCamera cam = testCamera();
  const testing::LineScene scene = testing::makeScene();
  const cv::Mat img = testing::renderScene(scene, cam, Pose(), 2.0, 1);
  LineDetectorOptions opt;
  opt.detector = GetParam();
  opt.downsample = (opt.detector == "edlines" || opt.detector == "fld") ? 2.0 : 1.0;
  LineDetector det(opt);
  std::vector<LineSegment> segs;
  det.detect(img, &segs);
  ASSERT_GT(segs.size(), 10u);
  const std::vector<LineSegment> edges = testing::projectEdges(scene, cam, Pose());
  int on_edge = 0;
  for (const LineSegment& s : segs) on_edge += testing::assignEdge(s, edges, 2.0) >= 0;
  // Some detections are edges of occluded quads cut by nearer ones (they lie on the nearer quad's edge and are
  // counted), a few are corners' stubs: most must lie on a true edge.
  EXPECT_GE(on_edge, static_cast<int>(0.85 * segs.size())) << on_edge << " of " << segs.size();
  for (const LineSegment& s : segs) EXPECT_GE(s.length(), opt.min_length_px - 1e-9);
  for (std::size_t k = 1; k < segs.size(); ++k) EXPECT_GE(segs[k - 1].length(), segs[k].length());
}

INSTANTIATE_TEST_SUITE_P(AllDetectors, DetectorTest, ::testing::Values("ed", "edlines", "fld", "lsd"));

TEST(LineDetector, RefinementIsSubPixelOnAStraightEdge) {
  // A dark / bright step along the line y = b + a (x - 100), rendered by exact pixel-area coverage (each pixel
  // integrates the step over its square, 8x8 supersampled), then blurred a little: the edge is exactly on the line.
  const double a = 0.3, b = 200.0;
  cv::Mat img = testing::coverageImage([&](double px, double py) {
    return (py > b + a * (px - 100.0) && px > 100.0 && px < 600.0) ? 190.0 : 60.0;
  });
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.8);
  LineDetector det(LineDetectorOptions{});
  std::vector<LineSegment> segs;
  det.detect(img, &segs);
  ASSERT_FALSE(segs.empty());
  const LineSegment& s = segs.front();
  EXPECT_GT(s.length(), 400.0);
  for (double t : {0.2, 0.5, 0.8}) {  // points along the segment
    const Vec2 p = s.s + t * (s.e - s.s);
    EXPECT_LT(std::abs((p - Vec2(100.0, b)).dot(Vec2(-a, 1.0).normalized())), 0.25) << "t = " << t;
  }
  const Vec2 n = Vec2(-a, 1.0).normalized();
  for (const Vec2& p : {s.s, s.e}) {
    if (p.x() < 110.0 || p.x() > 590.0) continue;  // endpoints near the step's ends sit on its corners
    const double dist = (p - Vec2(100.0, b)).dot(n);
    EXPECT_LT(std::abs(dist), 0.35) << "endpoint " << p.transpose();
  }
  // Bright below: walking s -> e, the gradient points along +n = (-d.y, d.x) (downwards here), so s is on the left.
  EXPECT_LT(s.s.x(), s.e.x());
  EXPECT_GT(s.normal().y(), 0.0);
}

TEST(LineDetector, TrimmedRefinementEndsAtTheEdgeAndIgnoresStructurePastIt) {
  // A predicted segment's extent is a guess. Here the edge y = 200 (dark above, bright below) ends at x = 400; past
  // it, up to x = 560, the boundary is crenellated (1.8 px above and below the line, alternately every 8 px). A
  // prediction along y = 200.3 from x = 150 to 560 finds those crenels within its +-3 px search: the plain
  // refinement keeps them (and the whole extent), the trimmed one drops the samples off its first fit, refits on the
  // edge and ends near x = 400.
  const auto boundary = [](double x) {
    if (x < 400.0) return 200.0;
    return (static_cast<int>(std::floor((x - 400.0) / 8.0)) % 2 == 0) ? 198.2 : 201.8;
  };
  cv::Mat img = testing::coverageImage(
      [&](double px, double py) { return (px > 100.0 && px < 600.0 && py > boundary(px)) ? 180.0 : 60.0; });
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.8);
  LineDetectorOptions opt;
  opt.refine_search_px = 3;
  opt.refine_max_samples = 60;
  const LineSegment predicted{Vec2(150.0, 200.3), Vec2(560.0, 200.3)};
  LineSegment plain = predicted, trimmed = predicted;
  double support_plain = 0.0, support_trimmed = 0.0;
  ASSERT_TRUE(refineSegment(img, opt, &plain, &support_plain));
  ASSERT_TRUE(refineSegment(img, opt, &trimmed, &support_trimmed, /*trim=*/true));
  const auto offEdge = [](const Vec2& p) { return std::abs(p.y() - 200.0); };
  // The trimmed segment lies on the true edge and ends where the edge ends (within a sample step, about 7 px).
  EXPECT_LT(offEdge(trimmed.s), 0.15);
  EXPECT_LT(offEdge(trimmed.e), 0.15);
  EXPECT_NEAR(std::max(trimmed.s.x(), trimmed.e.x()), 400.0, 8.0);
  EXPECT_NEAR(std::min(trimmed.s.x(), trimmed.e.x()), 150.0, 8.0);
  EXPECT_LT(support_trimmed, support_plain - 0.2);  // only the kept samples count
  EXPECT_GT(support_trimmed, 0.5);
  // The plain refinement keeps the predicted extent and is pulled off the edge by the crenels.
  EXPECT_NEAR(std::max(plain.s.x(), plain.e.x()), 560.0, 1.0);
  EXPECT_GT(std::max(offEdge(plain.s), offEdge(plain.e)), std::max(offEdge(trimmed.s), offEdge(trimmed.e)));
  // On a clean straight edge, trimming changes nothing but the extent's rounding.
  LineSegment clean{Vec2(150.0, 200.3), Vec2(380.0, 200.3)}, clean_trimmed = clean;
  ASSERT_TRUE(refineSegment(img, opt, &clean));
  ASSERT_TRUE(refineSegment(img, opt, &clean_trimmed, nullptr, true));
  EXPECT_LT(offEdge(clean_trimmed.s), 0.15);
  EXPECT_LT(offEdge(clean_trimmed.e), 0.15);
  EXPECT_LT((clean_trimmed.s - clean.s).norm(), 5.0);
  EXPECT_LT((clean_trimmed.e - clean.e).norm(), 5.0);
}

// A thin dark bar (two opposite edges `width` px apart along y = b + a (x - 100)) on a bright background, rendered
// by pixel-area coverage. Returns the segments found on each of the two edges (within 0.5 px, > 300 px long).
std::array<int, 2> detectBarEdges(const LineDetectorOptions& opt, double width, double far_grey = 170.0) {
  const double a = 0.2, b = 220.0;
  cv::Mat img = testing::coverageImage([&](double px, double py) {
    const double above = py - (b + a * (px - 100.0));
    const bool inside = px > 100.0 && px < 600.0;
    return inside && above > 0.0 && above < width ? 60.0 : inside && above >= width ? far_grey : 170.0;
  });
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.7);
  LineDetector det(opt);
  std::vector<LineSegment> segs;
  det.detect(img, &segs);
  std::array<int, 2> found{0, 0};
  const Vec2 n = Vec2(-a, 1.0).normalized();
  const double gap = width / std::sqrt(1.0 + a * a);  // the bar's width across it
  for (const LineSegment& s : segs) {
    if (s.length() < 300.0) continue;
    const double ds = (s.s - Vec2(100.0, b)).dot(n), de = (s.e - Vec2(100.0, b)).dot(n);
    for (int k = 0; k < 2; ++k) found[k] += std::abs(ds - k * gap) < 0.5 && std::abs(de - k * gap) < 0.5;
  }
  return found;
}

// Dark bar between a bright wall (170) and a mid-grey face (110): the half-size detection finds only the strong edge;
// the parallel-edge search finds the weaker one too, within 0.5 px.
TEST(LineDetector, ParallelEdgesOfThinBarsAreBothFound) {
  // OpenCV's EdgeDrawing on the half-size image fuses the bar's two edges; the parallel-edge search recovers the
  // second one.
  LineDetectorOptions opt;
  opt.detector = "edlines";
  opt.downsample = 2.0;
  for (double width : {2.5, 3.5}) {
    opt.parallel_edges = true;
    const std::array<int, 2> with = detectBarEdges(opt, width, 110.0);
    EXPECT_EQ(with[0], 1) << "width " << width;
    EXPECT_EQ(with[1], 1) << "width " << width;
    opt.parallel_edges = false;
    const std::array<int, 2> without = detectBarEdges(opt, width, 110.0);
    EXPECT_EQ(without[0], 1) << "width " << width;
    EXPECT_EQ(without[1], 0) << "width " << width;
  }
}

TEST(LineDetector, FullResolutionEdgeDrawingSeparatesThinBarEdges) {
  LineDetectorOptions opt;  // the default: "ed" at full resolution
  for (double width : {2.5, 3.5}) {
    for (bool parallel : {true, false}) {
      opt.parallel_edges = parallel;
      const std::array<int, 2> found = detectBarEdges(opt, width, 110.0);
      EXPECT_EQ(found[0], 1) << "width " << width << " parallel " << parallel;
      EXPECT_EQ(found[1], 1) << "width " << width << " parallel " << parallel;
    }
  }
}

TEST(LineDetector, DegenerateImagesNeitherCrashNorHang) {
  cv::Mat black(480, 752, CV_8UC1, cv::Scalar(0)), white(480, 752, CV_8UC1, cv::Scalar(255));
  cv::Mat noise(480, 752, CV_8UC1);
  cv::RNG rng(5);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  for (const std::string name : {"ed", "edlines", "fld", "lsd"}) {
    LineDetectorOptions opt;
    opt.detector = name;
    LineDetector det(opt);
    std::vector<LineSegment> segs;
    det.detect(black, &segs);
    EXPECT_TRUE(segs.empty()) << name;
    det.detect(white, &segs);
    EXPECT_TRUE(segs.empty()) << name;
    const auto t0 = std::chrono::steady_clock::now();
    det.detect(noise, &segs);
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 5.0) << name;
    EXPECT_LE(static_cast<int>(segs.size()), opt.max_segments);
    det.detect(cv::Mat(), &segs);
    EXPECT_TRUE(segs.empty());
    det.detect(cv::Mat(3, 3, CV_8UC1, cv::Scalar(7)), &segs);  // tiny
    EXPECT_TRUE(segs.empty());
  }
}

TEST(LineDetector, RejectsWrongImagesAndOptions) {
  LineDetector det(LineDetectorOptions{});
  std::vector<LineSegment> segs;
  EXPECT_THROW(det.detect(cv::Mat(10, 10, CV_8UC3), &segs), UsageError);
  LineDetectorOptions bad;
  bad.detector = "hough";
  try {
    LineDetector d(bad);
    FAIL() << "no ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("lines.detector.detector"), std::string::npos) << e.what();
  }
  LineDetectorOptions bad2;
  bad2.min_length_px = -1;
  EXPECT_THROW(LineDetector d(bad2), ConfigError);
}

}  // namespace
}  // namespace linnet
