// The published line map (line_map_curation.h): the lines within the sigma bound, unknown sigmas and malformed
// segments left out, every well-formed line with an infinite bound, bad bounds refused.
#include "linnet/estimator/line_map_curation.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <gtest/gtest.h>

namespace linnet {
namespace {

MapLine line(std::int64_t id, double y, double sigma, double length = 1.0) {
  MapLine l;
  l.id = id;
  l.a = Vec3(0.0, y, 0.0);
  l.b = Vec3(length, y, 0.0);
  l.sigma_m = sigma;
  l.observations = 5;
  return l;
}

const double kInf = std::numeric_limits<double>::infinity();

std::vector<MapLine> sample() {
  std::vector<MapLine> lines = {line(4, 0, 0.01),   line(2, 1, 0.03),       line(9, 2, 0.02),
                                line(3, 3, kInf),   line(5, 4, std::nan("")), line(6, 5, 0.001, 0.0),
                                line(7, 6, 0.001)};
  lines.back().b.x() = NAN;
  return lines;
}

TEST(LineMapCuration, PublishesTheLinesWithinTheSigmaBoundInTheirOrder) {
  LineMapOptions o;
  o.max_sigma_m = 0.02;
  LineMapCurationStats st;
  const std::vector<MapLine> out = curateLineMap(sample(), o, &st);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].id, 4);
  EXPECT_EQ(out[1].id, 9);  // the bound itself is in
  EXPECT_EQ(out[1].a, Vec3(0, 2, 0));
  EXPECT_EQ(st.input, 7u);
  EXPECT_EQ(st.uncertain, 5u);  // 2 (above), 3 (unknown), 5 (NaN), 6 (zero length), 7 (not finite)
  EXPECT_EQ(st.published, 2u);
  o.max_sigma_m = 0.0;
  EXPECT_TRUE(curateLineMap(sample(), o).empty());
}

TEST(LineMapCuration, AnInfiniteBoundPublishesEveryWellFormedLine) {
  LineMapOptions o;
  o.max_sigma_m = kInf;
  LineMapCurationStats st;
  const std::vector<MapLine> out = curateLineMap(sample(), o, &st);
  ASSERT_EQ(out.size(), 5u);
  EXPECT_EQ(out[3].id, 3);
  EXPECT_EQ(out[4].id, 5);
  EXPECT_EQ(st.uncertain, 2u);
}

TEST(LineMapCuration, DefaultBoundIsTwoCentimetres) {
  EXPECT_EQ(LineMapOptions().max_sigma_m, 0.02);
  EXPECT_EQ(curateLineMap(sample(), LineMapOptions()).size(), 2u);
}

TEST(LineMapCuration, RefusesANegativeOrNaNBound) {
  LineMapOptions o;
  o.max_sigma_m = -0.01;
  EXPECT_THROW(curateLineMap(sample(), o), std::invalid_argument);
  o.max_sigma_m = std::nan("");
  EXPECT_THROW(curateLineMap(sample(), o), std::invalid_argument);
}

}  // namespace
}  // namespace linnet
