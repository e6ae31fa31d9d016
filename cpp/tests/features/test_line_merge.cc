// Merging of broken segments: synthetic geometry and a real detection of an edge interrupted by an occluder.
#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/features/line_detector.h"
#include "linnet/features/line_lbd.h"
#include "linnet/features/line_merge.h"

namespace linnet {
namespace {

LineSegment seg(double x0, double y0, double x1, double y1) {
  LineSegment s;
  s.s = Vec2(x0, y0);
  s.e = Vec2(x1, y1);
  return s;
}

// Descriptor 0 everywhere except segments whose midpoint lies right of x = 1000 (all bits set).
LbdDescriptor fakeDescriptor(const LineSegment& s) {
  const std::uint64_t v = s.midpoint().x() > 1000.0 ? ~std::uint64_t{0} : 0;
  return {v, v, v, v};
}

TEST(LineMerge, MergesCollinearPiecesKeepingTheFarthestEndpoints) {
  std::vector<LineSegment> segs = {seg(100, 100, 200, 100), seg(215, 100.5, 300, 101), seg(305, 101, 340, 101.2)};
  std::vector<LbdDescriptor> desc;
  std::vector<char> described;
  const int merges = mergeSegments(LineMergeOptions{}, fakeDescriptor, &segs, &desc, &described);
  EXPECT_EQ(merges, 2);
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_NEAR((segs[0].s - Vec2(100, 100)).norm(), 0.0, 1e-9);
  EXPECT_NEAR((segs[0].e - Vec2(340, 101.2)).norm(), 0.0, 1e-9);
  ASSERT_EQ(desc.size(), 1u);
  ASSERT_EQ(described.size(), 1u);
}

TEST(LineMerge, KeepsApartWhatIsNotOneLine) {
  const LineMergeOptions opt;
  auto count_after = [&](std::vector<LineSegment> segs) {
    std::vector<LbdDescriptor> desc;
    std::vector<char> described;
    mergeSegments(opt, fakeDescriptor, &segs, &desc, &described);
    return segs.size();
  };
  EXPECT_EQ(count_after({seg(100, 100, 200, 100), seg(210, 110, 300, 110)}), 2u);  // parallel, 10 px apart
  EXPECT_EQ(count_after({seg(100, 100, 200, 100), seg(300, 100, 210, 100)}), 2u);  // opposite polarity
  EXPECT_EQ(count_after({seg(100, 100, 200, 100), seg(260, 100, 360, 100)}), 2u);  // 60 px gap
  EXPECT_EQ(count_after({seg(100, 100, 200, 100), seg(210, 100, 300, 130)}), 2u);  // 18 degrees apart
  // Geometry fits but the descriptors disagree.
  EXPECT_EQ(count_after({seg(900, 100, 1000, 100), seg(1010, 100, 1200, 100)}), 2u);
  // Overlapping duplicates merge.
  EXPECT_EQ(count_after({seg(100, 100, 200, 100), seg(150, 100.5, 250, 100.5)}), 1u);
  LineMergeOptions off;
  off.enabled = false;
  std::vector<LineSegment> segs = {seg(100, 100, 200, 100), seg(205, 100, 300, 100)};
  std::vector<LbdDescriptor> desc;
  std::vector<char> described;
  EXPECT_EQ(mergeSegments(off, fakeDescriptor, &segs, &desc, &described), 0);
  EXPECT_EQ(segs.size(), 2u);
}

TEST(LineMerge, RejectsMismatchedSizes) {
  std::vector<LineSegment> segs = {seg(0, 0, 10, 0)};
  std::vector<LbdDescriptor> desc(2);
  std::vector<char> described(2, 0);
  EXPECT_THROW(mergeSegments(LineMergeOptions{}, fakeDescriptor, &segs, &desc, &described), UsageError);
}

TEST(LineMerge, JoinsAnEdgeBrokenByAnOccluder) {
  // A horizontal step edge at y = 240 from x = 80 to 680, interrupted by a grey disc in the middle.
  cv::Mat img(480, 752, CV_8UC1, cv::Scalar(50));
  cv::rectangle(img, cv::Point(80, 240), cv::Point(680, 470), cv::Scalar(200), cv::FILLED);
  cv::circle(img, cv::Point(380, 240), 6, cv::Scalar(125), cv::FILLED, cv::LINE_AA);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 0.8);
  LineDetectorOptions dopt;
  dopt.downsample = 1;
  LineDetector det(dopt);
  std::vector<LineSegment> segs;
  det.detect(img, &segs);
  auto on_edge = [](const LineSegment& s) {
    return std::abs(s.s.y() - 240.0) < 2.0 && std::abs(s.e.y() - 240.0) < 2.0 && s.length() > 100.0;
  };
  int pieces = 0;
  for (const LineSegment& s : segs) pieces += on_edge(s);
  for (const LineSegment& s : segs)
    if (on_edge(s)) std::printf("  piece %.1f,%.1f -> %.1f,%.1f\n", s.s.x(), s.s.y(), s.e.x(), s.e.y());
  ASSERT_GE(pieces, 2) << "the occluder should break the detection";
  const LbdOptions lopt;
  const SegmentDescriber describe = [&](const LineSegment& s) {
    return binarizeLbd(computeLbdFloat(img, lopt, s));
  };
  std::vector<LbdDescriptor> desc;
  std::vector<char> described;
  mergeSegments(LineMergeOptions{}, describe, &segs, &desc, &described);
  int merged = 0;
  for (const LineSegment& s : segs)
    if (on_edge(s)) {
      ++merged;
      EXPECT_GT(s.length(), 560.0);
    }
  EXPECT_EQ(merged, 1);
}

}  // namespace
}  // namespace linnet
