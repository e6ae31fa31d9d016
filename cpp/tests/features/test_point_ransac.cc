// Two-view RANSAC for point tracks: known-rotation 2-point and fundamental-matrix variants on synthetic scenes.
#include <gtest/gtest.h>

#include <random>

#include "linnet/core/error.h"
#include "linnet/core/pose.h"
#include "linnet/features/point_ransac.h"

namespace linnet {
namespace {

struct TwoViews {
  std::vector<Vec2> prev, cur;
  std::vector<bool> outlier;
};

// Points 2-10 m in front of the previous camera, seen again after (R_cur_prev, t_cur_prev); a share of the current
// observations replaced by random ones (outliers), pixel noise sigma_px with a 460 px focal length.
TwoViews makeViews(const Mat3& R, const Vec3& t, int n, double outlier_share, double sigma_px, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-0.6, 0.6), uy(-0.45, 0.45), depth(2.0, 10.0), u01(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, sigma_px / 460.0);
  TwoViews v;
  while (static_cast<int>(v.prev.size()) < n) {
    const Vec2 a(ux(rng), uy(rng));
    const Vec3 P = depth(rng) * Vec3(a.x(), a.y(), 1.0);
    const Vec3 Q = R * P + t;
    if (Q.z() < 0.5) continue;
    Vec2 b = Q.head<2>() / Q.z() + Vec2(noise(rng), noise(rng));
    const bool out = u01(rng) < outlier_share;
    if (out) b = Vec2(ux(rng), uy(rng));
    v.prev.push_back(a + Vec2(noise(rng), noise(rng)));
    v.cur.push_back(b);
    v.outlier.push_back(out);
  }
  return v;
}

void expectSeparates(const TwoViews& v, const std::vector<unsigned char>& inl, double min_kept, double min_rejected) {
  int in_total = 0, in_kept = 0, out_total = 0, out_rejected = 0;
  for (std::size_t i = 0; i < v.prev.size(); ++i) {
    if (v.outlier[i]) {
      ++out_total;
      out_rejected += inl[i] == 0;
    } else {
      ++in_total;
      in_kept += inl[i] != 0;
    }
  }
  EXPECT_GE(in_kept, min_kept * in_total) << in_kept << " of " << in_total << " inliers kept";
  EXPECT_GE(out_rejected, min_rejected * out_total) << out_rejected << " of " << out_total << " outliers rejected";
}

TEST(PointRansac, KnownRotationWithTranslation) {
  const Mat3 R = expSO3(Vec3(0.02, -0.05, 0.01)).toRotationMatrix();
  const TwoViews v = makeViews(R, Vec3(0.15, 0.02, 0.05), 150, 0.2, 0.3, 1);
  TwoViewRansacParams p;
  p.focal_px = 460.0;
  const auto inl = knownRotationInliers(v.prev, v.cur, R, p);
  expectSeparates(v, inl, 0.97, 0.9);
  EXPECT_EQ(inl, knownRotationInliers(v.prev, v.cur, R, p));  // deterministic
}

TEST(PointRansac, KnownRotationStaticAndPureRotation) {
  for (const Vec3& w : {Vec3(0, 0, 0), Vec3(0.03, 0.08, -0.02)}) {
    const Mat3 R = expSO3(w).toRotationMatrix();
    const TwoViews v = makeViews(R, Vec3::Zero(), 150, 0.2, 0.3, 2);
    TwoViewRansacParams p;
    p.focal_px = 460.0;
    // 0.3 px noise in both views: ~6% of the inliers lie beyond the 1 px threshold.
    expectSeparates(v, knownRotationInliers(v.prev, v.cur, R, p), 0.9, 0.9);
  }
}

TEST(PointRansac, FundamentalWithTranslation) {
  const Mat3 R = expSO3(Vec3(0.02, -0.05, 0.01)).toRotationMatrix();
  const TwoViews v = makeViews(R, Vec3(0.3, 0.05, 0.1), 150, 0.2, 0.3, 3);
  TwoViewRansacParams p;
  p.focal_px = 460.0;
  const auto inl = fundamentalInliers(v.prev, v.cur, p);
  expectSeparates(v, inl, 0.95, 0.85);
  EXPECT_EQ(inl, fundamentalInliers(v.prev, v.cur, p));
}

TEST(PointRansac, TooFewPointsKeepsAll) {
  const TwoViews v = makeViews(Mat3::Identity(), Vec3(0.1, 0, 0), 6, 0.5, 0.3, 4);
  TwoViewRansacParams p;
  const auto inl = fundamentalInliers(v.prev, v.cur, p);
  EXPECT_EQ(inl, std::vector<unsigned char>(6, 1));
  EXPECT_THROW(fundamentalInliers(v.prev, std::vector<Vec2>(3), p), UsageError);
  EXPECT_THROW(knownRotationInliers(v.prev, std::vector<Vec2>(3), Mat3::Identity(), p), UsageError);
}

}  // namespace
}  // namespace linnet
