// Pose-only refinement of T_W_B from known world points and their cam0 observations (perspective-n-point by
// nonlinear least squares from an initial guess; the points come from stereo triangulation, so no RANSAC is needed
// beyond the robust loss and one re-weighted pass that drops gross outliers).
#pragma once

#include <vector>

#include "linnet/core/pose.h"

namespace linnet {

struct PnpResult {
  bool ok = false;
  double rms_px = 0.0;    // RMS reprojection error over the inliers, pixels
  int inliers = 0;
};

/// Refines *T_W_B (initial guess in, estimate out) minimising the reprojection error of p_W[i] in cam0
/// (T_B_C0) against the normalised observations uv[i]. `focal_length` converts to pixels; `outlier_px` drops
/// points after a first solve.
PnpResult refinePosePnp(const std::vector<Vec3>& p_W, const std::vector<Vec2>& uv, const Pose& T_B_C0,
                        double focal_length, double outlier_px, Pose* T_W_B);

}  // namespace linnet
