// Two-view outlier rejection for tracked points, on undistorted normalised coordinates.
#pragma once

#include <cstdint>
#include <vector>

#include "linnet/core/types.h"

namespace linnet {

struct TwoViewRansacParams {
  double focal_px = 460.0;        // converts normalised distances to pixels
  double threshold_px = 1.0;      // epipolar distance (pixels) below which a point is an inlier
  double confidence = 0.99;       // RANSAC stopping confidence
  int max_iterations = 200;       // hypotheses at most
  std::uint32_t seed = 0x5eed;    // fixed: deterministic
};

/// Fundamental-matrix RANSAC (OpenCV's 8-point RANSAC on focal-scaled normalised coordinates, as VINS-Mono does),
/// then a least-squares refit on the inliers and re-classification by the Sampson distance. Returns 1 per inlier. With fewer than 8 points, or when RANSAC finds no model, every point is kept.
std::vector<unsigned char> fundamentalInliers(const std::vector<Vec2>& uv_prev, const std::vector<Vec2>& uv_cur,
                                              const TwoViewRansacParams& params);

/// RANSAC for the translation direction when the rotation R_cur_prev is known (from the gyroscope), two points per
/// hypothesis: with a = R f_prev and b = f_cur, the epipolar constraint b . (t x a) = 0 is t . (a x b) = 0, so two
/// correspondences give t = (a1 x b1) x (a2 x b2) (Kneip, Chli & Siegwart, BMVC 2011; Troiani et al., ICRA 2014).
/// A point is an inlier when its distance to the epipolar line t x a is below the threshold, or when its de-rotated
/// flow |pi(a) - b| is (consistent with no translation: static and purely rotating cameras). Deterministic.
std::vector<unsigned char> knownRotationInliers(const std::vector<Vec2>& uv_prev, const std::vector<Vec2>& uv_cur,
                                                const Mat3& R_cur_prev, const TwoViewRansacParams& params);

}  // namespace linnet
