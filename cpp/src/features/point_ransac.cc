// Fundamental-matrix RANSAC and 2-point known-rotation RANSAC.
#include "linnet/features/point_ransac.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <opencv2/calib3d.hpp>

#include "linnet/core/error.h"

namespace linnet {

std::vector<unsigned char> fundamentalInliers(const std::vector<Vec2>& uv_prev, const std::vector<Vec2>& uv_cur,
                                              const TwoViewRansacParams& p) {
  if (uv_prev.size() != uv_cur.size()) throw UsageError("fundamentalInliers: point lists differ in length");
  const std::size_t n = uv_prev.size();
  std::vector<unsigned char> inl(n, 1);
  if (n < 8) return inl;
  std::vector<cv::Point2d> a(n), b(n);
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = cv::Point2d(p.focal_px * uv_prev[i].x(), p.focal_px * uv_prev[i].y());
    b[i] = cv::Point2d(p.focal_px * uv_cur[i].x(), p.focal_px * uv_cur[i].y());
  }
  std::vector<unsigned char> mask;
  cv::Mat F = cv::findFundamentalMat(a, b, cv::FM_RANSAC, p.threshold_px, p.confidence, p.max_iterations, mask);
  if (F.empty() || mask.size() != n) return inl;
  // A minimal-sample F fits the noise of its 8 points: refit on all inliers (normalised 8-point least squares) and
  // re-classify by the Sampson distance, twice.
  for (int round = 0; round < 2; ++round) {
    std::vector<cv::Point2d> ia, ib;
    for (std::size_t i = 0; i < n; ++i)
      if (mask[i]) {
        ia.push_back(a[i]);
        ib.push_back(b[i]);
      }
    if (ia.size() < 8) break;
    const cv::Mat F8 = cv::findFundamentalMat(ia, ib, cv::FM_8POINT);
    if (F8.rows != 3 || F8.cols != 3) break;
    Mat3 Fe;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Fe(r, c) = F8.at<double>(r, c);
    std::vector<unsigned char> next(n, 0);
    std::size_t count = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3 x1(a[i].x, a[i].y, 1.0), x2(b[i].x, b[i].y, 1.0);
      const Vec3 l2 = Fe * x1, l1 = Fe.transpose() * x2;
      const double e = x2.dot(l2);
      const double den = l2.head<2>().squaredNorm() + l1.head<2>().squaredNorm();
      const bool ok = den > 0.0 && e * e / den < p.threshold_px * p.threshold_px;
      next[i] = ok ? 1 : 0;
      count += ok ? 1 : 0;
    }
    if (count < ia.size() / 2) break;  // the refit went astray: keep the RANSAC answer
    mask = std::move(next);
  }
  return mask;
}

std::vector<unsigned char> knownRotationInliers(const std::vector<Vec2>& uv_prev, const std::vector<Vec2>& uv_cur,
                                                const Mat3& R_cur_prev, const TwoViewRansacParams& p) {
  if (uv_prev.size() != uv_cur.size()) throw UsageError("knownRotationInliers: point lists differ in length");
  const std::size_t n = uv_prev.size();
  const double th = p.threshold_px / p.focal_px;  // normalised units
  std::vector<Vec3> a(n), b(n), nrm(n);
  std::vector<unsigned char> still(n, 0);  // de-rotated flow below threshold
  int n_still = 0;
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = R_cur_prev * Vec3(uv_prev[i].x(), uv_prev[i].y(), 1.0);
    b[i] = Vec3(uv_cur[i].x(), uv_cur[i].y(), 1.0);
    nrm[i] = a[i].cross(b[i]);
    const bool ok = a[i].z() > 1e-9 && (a[i].head<2>() / a[i].z() - uv_cur[i]).norm() < th;
    still[i] = ok ? 1 : 0;
    n_still += ok ? 1 : 0;
  }
  std::vector<unsigned char> best = still;
  int best_count = n_still;
  if (n < 2) return std::vector<unsigned char>(n, 1);

  const auto score = [&](const Vec3& t, std::vector<unsigned char>* inl) {
    int count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      bool ok = still[k] != 0;
      if (!ok) {
        const Vec3 l = t.cross(a[k]);
        const double ln = std::hypot(l.x(), l.y());
        ok = ln > 1e-12 && std::abs(b[k].dot(l)) / ln < th;
      }
      (*inl)[k] = ok ? 1 : 0;
      count += ok ? 1 : 0;
    }
    return count;
  };

  std::mt19937 rng(p.seed);
  std::vector<unsigned char> cand(n);
  int needed = p.max_iterations;
  for (int it = 0; it < std::min(needed, p.max_iterations); ++it) {
    const std::size_t i = rng() % n;
    std::size_t j = rng() % (n - 1);
    if (j >= i) ++j;
    const Vec3 t = nrm[i].cross(nrm[j]);
    if (t.norm() < 1e-12) continue;  // degenerate pair (e.g. both without translation-induced flow)
    const int c = score(t.normalized(), &cand);
    if (c > best_count) {
      best_count = c;
      best = cand;
      const double w = static_cast<double>(c) / static_cast<double>(n);
      const double denom = std::log(std::max(1e-12, 1.0 - w * w));
      needed = denom < 0.0 ? static_cast<int>(std::ceil(std::log(1.0 - p.confidence) / denom)) : 0;
    }
  }
  return best;
}

}  // namespace linnet
