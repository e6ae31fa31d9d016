// Pinhole, radial-tangential and equidistant (Kannala-Brandt) distortion with analytic Jacobians.
#include "linnet/camera/distortion_models.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "linnet/core/error.h"

namespace linnet {

// ---------------------------------------------------------------------------------------------- pinhole
Vec2 PinholeCamera::distort(const Vec2& uv, Mat2* J) const {
  if (J) *J << fx_, 0.0, 0.0, fy_;
  return Vec2(fx_ * uv.x() + cx_, fy_ * uv.y() + cy_);
}

bool PinholeCamera::undistort(const Vec2& px, Vec2* uv) const {
  *uv = Vec2((px.x() - cx_) / fx_, (px.y() - cy_) / fy_);
  return true;
}

// ---------------------------------------------------------------------------------------------- radtan
PinholeRadtanCamera::PinholeRadtanCamera(int width, int height, double fx, double fy, double cx, double cy,
                                         const std::vector<double>& c)
    : CameraModel(width, height, fx, fy, cx, cy) {
  if (c.size() != 4 && c.size() != 5)
    throw ConfigError("camera calibration key 'distortion_coeffs': radtan needs 4 or 5 values, got " +
                      std::to_string(c.size()));
  k1_ = c[0];
  k2_ = c[1];
  p1_ = c[2];
  p2_ = c[3];
  has_k3_ = c.size() == 5;
  k3_ = has_k3_ ? c[4] : 0.0;
}

std::vector<double> PinholeRadtanCamera::distortionCoeffs() const {
  std::vector<double> c{k1_, k2_, p1_, p2_};
  if (has_k3_) c.push_back(k3_);
  return c;
}

Vec2 PinholeRadtanCamera::distort(const Vec2& uv, Mat2* J) const {
  const double x = uv.x(), y = uv.y();
  const double x2 = x * x, y2 = y * y, xy = x * y, r2 = x2 + y2;
  const double a = 1.0 + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
  const double xd = a * x + 2.0 * p1_ * xy + p2_ * (r2 + 2.0 * x2);
  const double yd = a * y + p1_ * (r2 + 2.0 * y2) + 2.0 * p2_ * xy;
  if (J) {
    const double da = 2.0 * k1_ + r2 * (4.0 * k2_ + 6.0 * k3_ * r2);  // d a / d r2 * 2
    const double dxx = a + da * x2 + 2.0 * p1_ * y + 6.0 * p2_ * x;
    const double dxy = da * xy + 2.0 * p1_ * x + 2.0 * p2_ * y;
    const double dyy = a + da * y2 + 6.0 * p1_ * y + 2.0 * p2_ * x;
    *J << fx_ * dxx, fx_ * dxy, fy_ * dxy, fy_ * dyy;
  }
  return Vec2(fx_ * xd + cx_, fy_ * yd + cy_);
}

// ---------------------------------------------------------------------------------------------- equidistant
PinholeEquidistantCamera::PinholeEquidistantCamera(int width, int height, double fx, double fy, double cx, double cy,
                                                   const std::vector<double>& c)
    : CameraModel(width, height, fx, fy, cx, cy) {
  if (c.size() != 4)
    throw ConfigError("camera calibration key 'distortion_coeffs': equidistant needs 4 values, got " +
                      std::to_string(c.size()));
  k_ = {c[0], c[1], c[2], c[3]};
}

Vec2 PinholeEquidistantCamera::distort(const Vec2& uv, Mat2* J) const {
  const double r2 = uv.squaredNorm();
  const double r = std::sqrt(r2);
  if (r < 1e-9) {
    // theta_d / r -> 1 as r -> 0 (its r-derivative vanishes there).
    if (J) *J << fx_, 0.0, 0.0, fy_;
    return Vec2(fx_ * uv.x() + cx_, fy_ * uv.y() + cy_);
  }
  const double th = std::atan(r), t2 = th * th;
  const double poly = 1.0 + t2 * (k_[0] + t2 * (k_[1] + t2 * (k_[2] + t2 * k_[3])));
  const double thd = th * poly;
  const double s = thd / r;
  if (J) {
    const double dthd_dth = 1.0 + t2 * (3.0 * k_[0] + t2 * (5.0 * k_[1] + t2 * (7.0 * k_[2] + t2 * 9.0 * k_[3])));
    const double dth_dr = 1.0 / (1.0 + r2);
    const double ds_dr = (dthd_dth * dth_dr * r - thd) / r2;
    Mat2 Jn = s * Mat2::Identity() + (ds_dr / r) * uv * uv.transpose();
    Jn.row(0) *= fx_;
    Jn.row(1) *= fy_;
    *J = Jn;
  }
  return Vec2(fx_ * s * uv.x() + cx_, fy_ * s * uv.y() + cy_);
}

bool PinholeEquidistantCamera::undistort(const Vec2& px, Vec2* uv) const {
  const Vec2 xd((px.x() - cx_) / fx_, (px.y() - cy_) / fy_);
  const double thd = xd.norm();
  if (thd < 1e-12) {
    *uv = xd;
    return true;
  }
  // Solve theta (1 + k1 theta^2 + ...) = theta_d for theta in [0, pi/2) by Newton's method from theta = theta_d.
  double th = std::min(thd, 1.5);
  bool converged = false;
  for (int it = 0; it < 40; ++it) {
    const double t2 = th * th;
    const double g = th * (1.0 + t2 * (k_[0] + t2 * (k_[1] + t2 * (k_[2] + t2 * k_[3])))) - thd;
    const double dg = 1.0 + t2 * (3.0 * k_[0] + t2 * (5.0 * k_[1] + t2 * (7.0 * k_[2] + t2 * 9.0 * k_[3])));
    if (!(dg > 1e-9)) return false;  // the model folds: not invertible here
    const double step = g / dg;
    th -= step;
    if (!std::isfinite(th) || th < 0.0) return false;
    if (std::abs(step) < 1e-15 * std::max(1.0, th)) {
      converged = true;
      break;
    }
  }
  if (!converged || th >= std::numbers::pi / 2.0 - 1e-9) return false;
  const double r = std::tan(th);
  const Vec2 cand = xd * (r / thd);
  // Same acceptance rule as the generic path: reprojection residual in normalised units.
  const Vec2 res = distort(cand) - px;
  if (!(Vec2(res.x() / fx_, res.y() / fy_).norm() < 1e-10)) return false;
  *uv = cand;
  return true;
}

}  // namespace linnet
