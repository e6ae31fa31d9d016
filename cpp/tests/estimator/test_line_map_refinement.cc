// Map-line refinement on all sightings (line_map_refinement.h): it recovers a line from noisy sightings despite a
// gross outlier, never hands back a worse line, back-projects segments within the depth range only, and predicts its
// endpoints' error as a Monte-Carlo run over noisy sightings measures it.
#include "linnet/estimator/line_map_refinement.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "linnet/geometry/plucker.h"

namespace linnet {
namespace {

constexpr double kFocal = 460.0;
const Vec3 kA(-0.4, -0.7, 4.0), kB(0.3, 0.8, 4.6);  // a far line, 4-4.6 m ahead

Vec2 project(const Pose& T_W_C, const Vec3& p_W) {
  const Vec3 p = T_W_C.inverse() * p_W;
  return p.head<2>() / p.z();
}

/// Cameras moving 1.2 m sideways while looking along +z; endpoints with `noise_px` pixel noise.
std::vector<LineSighting> sightings(std::mt19937& rng, double noise_px) {
  std::normal_distribution<double> n(0.0, noise_px / kFocal);
  std::vector<LineSighting> out;
  for (int k = 0; k < 25; ++k) {
    LineSighting s;
    s.T_W_C = Pose(expSO3(Vec3(0.0, 0.01 * k, 0.0)), Vec3(0.05 * k, 0.01 * std::sin(k), 0.0));
    s.s = project(s.T_W_C, kA + 0.1 * (kB - kA)) + Vec2(n(rng), n(rng));
    s.e = project(s.T_W_C, kA + 0.9 * (kB - kA)) + Vec2(n(rng), n(rng));
    out.push_back(s);
  }
  return out;
}

double offMetres(const Vec6& L) { return std::max(pluckerPointDistance(L, kA), pluckerPointDistance(L, kB)); }

TEST(LineMapRefinement, RecoversAFarLineFromNoisySightingsDespiteAnOutlier) {
  std::mt19937 rng(3);
  std::vector<LineSighting> s = sightings(rng, 0.5);
  s[7].s += Vec2(40.0, -25.0) / kFocal;  // a mismatched observation
  // Start as a stereo-only triangulation of a 4 m line may be: 15 cm and about 3 deg off.
  Vec6 L = normalisePlucker(pluckerFromPoints(kA + Vec3(0.15, 0.0, 0.1), kB + Vec3(0.1, 0.05, -0.2)));
  const double before = offMetres(L);
  ASSERT_GT(before, 0.1);
  LineRefinementOptions o;
  o.focal_px = kFocal;
  ASSERT_TRUE(refineLine(s, o, &L));
  EXPECT_LT(offMetres(L), 0.02) << "from " << before;
  EXPECT_NEAR(L.norm(), 1.0, 1e-9);
}

TEST(LineMapRefinement, NeverReturnsAWorseLine) {
  std::mt19937 rng(4);
  const std::vector<LineSighting> s = sightings(rng, 0.0);
  Vec6 L = normalisePlucker(pluckerFromPoints(kA, kB));  // exact already
  const Vec6 L0 = L;
  LineRefinementOptions o;
  o.focal_px = kFocal;
  EXPECT_FALSE(refineLine(s, o, &L) && meanSightingErrorPx(L, s, kFocal) > meanSightingErrorPx(L0, s, kFocal));
  std::vector<LineSighting> one(s.begin(), s.begin() + 1);
  Vec6 L1 = L0;
  EXPECT_FALSE(refineLine(one, o, &L1));  // a single sighting does not fix a line
  EXPECT_EQ(L1, L0);
}

// The predicted endpoint standard deviation against the RMS endpoint error of refinements from 200 noise draws, for a
// wide baseline (25 cameras over 1.2 m) and a narrow one (the first 4 cameras, 0.15 m): within 25 %, and the narrow
// baseline's prediction several times the wide one's. A line seen from one centre only has no finite prediction.
TEST(LineMapRefinement, EndpointSigmaMatchesTheMonteCarloError) {
  constexpr double kNoisePx = 1.0;
  const Vec3 a = kA + 0.1 * (kB - kA), b = kA + 0.9 * (kB - kA);  // the observed extent
  double predicted[2] = {0.0, 0.0};
  for (int narrow = 0; narrow < 2; ++narrow) {
    std::mt19937 rng(11 + narrow);
    const std::size_t n = narrow ? 4 : 25;
    const Vec6 L_true = normalisePlucker(pluckerFromPoints(kA, kB));
    {
      std::vector<LineSighting> exact = sightings(rng, 0.0);
      exact.resize(n);
      predicted[narrow] = lineEndpointSigmaM(L_true, exact, a, b, kFocal, kNoisePx);
    }
    double sum_sq_a = 0.0, sum_sq_b = 0.0;
    constexpr int kDraws = 200;
    LineRefinementOptions o;
    o.focal_px = kFocal;
    o.huber_px = 100.0;  // least squares, as the prediction assumes
    o.max_iterations = 50;
    for (int k = 0; k < kDraws; ++k) {
      std::vector<LineSighting> s = sightings(rng, kNoisePx);
      s.resize(n);
      Vec6 L = L_true;
      refineLine(s, o, &L);
      sum_sq_a += std::pow(pluckerPointDistance(L, a), 2);
      sum_sq_b += std::pow(pluckerPointDistance(L, b), 2);
    }
    const double measured = std::sqrt(std::max(sum_sq_a, sum_sq_b) / kDraws);
    EXPECT_NEAR(predicted[narrow] / measured, 1.0, 0.25) << (narrow ? "narrow" : "wide") << " baseline: predicted "
                                                         << predicted[narrow] << " m, measured " << measured << " m";
  }
  EXPECT_GT(predicted[1], 3.0 * predicted[0]);
  std::mt19937 rng(5);
  std::vector<LineSighting> same_centre = sightings(rng, 0.0);
  for (LineSighting& o : same_centre) o.T_W_C.p = Vec3::Zero();  // rotations only: depth unobservable
  EXPECT_TRUE(std::isinf(
      lineEndpointSigmaM(normalisePlucker(pluckerFromPoints(kA, kB)), same_centre, a, b, kFocal, kNoisePx)));
}

TEST(LineMapRefinement, BackProjectionRespectsTheDepthRange) {
  const Vec6 L = normalisePlucker(pluckerFromPoints(kA, kB));
  const Pose T_W_C;
  const Vec2 s = project(T_W_C, kA), e = project(T_W_C, kB);
  Vec3 a, b;
  ASSERT_TRUE(backProjectSegment(L, T_W_C, s, e, 0.1, 30.0, &a, &b));
  EXPECT_LT((a - kA).norm(), 1e-9);
  EXPECT_LT((b - kB).norm(), 1e-9);
  EXPECT_FALSE(backProjectSegment(L, T_W_C, s, e, 0.1, 4.2, &a, &b));  // kB is 4.6 m deep
}

}  // namespace
}  // namespace linnet
