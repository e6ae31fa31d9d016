// One line on all its sightings, poses fixed (see line_map_refinement.h).
#include "linnet/estimator/line_map_refinement.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <ceres/loss_function.h>

#include "linnet/estimator/manifolds.h"
#include "linnet/geometry/plucker.h"

namespace linnet {

double meanSightingErrorPx(const Vec6& L_W, const std::vector<LineSighting>& sightings, double focal_px) {
  if (sightings.empty()) return std::numeric_limits<double>::infinity();
  double sum = 0.0;
  for (const LineSighting& o : sightings) sum += lineReprojectionErrorPx(L_W, o.T_W_C, o.s, o.e, focal_px);
  return sum / static_cast<double>(sightings.size());
}

bool backProjectSegment(const Vec6& L_W, const Pose& T_W_C, const Vec2& s, const Vec2& e, double min_depth_m,
                        double max_depth_m, Vec3* a, Vec3* b) {
  const Vec2* ends[2] = {&s, &e};
  Vec3* out[2] = {a, b};
  for (int k = 0; k < 2; ++k) {
    const Vec3 ray = T_W_C.q * Vec3(ends[k]->x(), ends[k]->y(), 1.0);
    const std::optional<RayLinePoint> p = closestPointToRay(L_W, T_W_C.p, ray);
    if (!p || p->ray_t < min_depth_m || p->ray_t > max_depth_m) return false;
    *out[k] = p->on_line;
  }
  return true;
}

void extendOnLine(const Vec6& L, const Vec3& a, const Vec3& b, bool* has_extent, Vec3* ext_a, Vec3* ext_b) {
  const Vec3 u = pluckerDirection(L), P0 = pluckerClosestPointToOrigin(L);
  double lo = (a - P0).dot(u), hi = (b - P0).dot(u);
  if (lo > hi) std::swap(lo, hi);
  if (*has_extent) {
    const double ta = (*ext_a - P0).dot(u), tb = (*ext_b - P0).dot(u);
    lo = std::min({lo, ta, tb});
    hi = std::max({hi, ta, tb});
  }
  *ext_a = P0 + lo * u;
  *ext_b = P0 + hi * u;
  *has_extent = true;
}

bool extentOnSightings(const Vec6& L, const std::vector<LineSighting>& sightings, double min_depth_m,
                       double max_depth_m, Vec3* a, Vec3* b) {
  bool has_extent = false;
  for (const LineSighting& o : sightings) {
    Vec3 pa, pb;
    if (backProjectSegment(L, o.T_W_C, o.s, o.e, min_depth_m, max_depth_m, &pa, &pb))
      extendOnLine(L, pa, pb, &has_extent, a, b);
  }
  return has_extent;
}

bool refineLine(const std::vector<LineSighting>& sightings, const LineRefinementOptions& options, Vec6* L_W) {
  if (sightings.size() < 2 || !L_W->allFinite()) return false;
  const double before = meanSightingErrorPx(*L_W, sightings, options.focal_px);
  if (!std::isfinite(before)) return false;

  // Levenberg-Marquardt on the line's 4 tangent coordinates, the sightings' cameras held (they are the factors'
  // "bodies", identity extrinsics). Huber as iteratively reweighted least squares (Ceres' corrector for a loss with
  // rho'' = 0). A line has a few dozen 2-row residuals: a general solver's per-problem set-up would cost more than
  // this arithmetic, and it runs for every line that leaves the window.
  const LineManifold manifold;
  const ceres::HuberLoss loss(options.huber_px);  // on residuals in pixels (sqrt_info = focal)
  // The cameras are held: each sighting's projection and pose terms are computed once, not at every evaluation.
  std::vector<LineProjection> projections;
  std::vector<LineProjection::PoseTerms> terms(sightings.size());
  projections.reserve(sightings.size());
  for (std::size_t k = 0; k < sightings.size(); ++k) {
    projections.emplace_back(sightings[k].s, sightings[k].e, Pose(), options.focal_px);
    projections.back().poseTerms(sightings[k].T_W_C, &terms[k]);
  }
  // Robust cost 0.5 sum rho(|r|^2); with H and g also the reweighted normal equations in the tangent space.
  const auto cost = [&](const Vec6& L, Eigen::Matrix4d* H, Eigen::Vector4d* g) {
    Eigen::Matrix<double, kLineAmbientSize, kLineTangentSize, Eigen::RowMajor> plus;
    if (H != nullptr) {
      manifold.PlusJacobian(L.data(), plus.data());
      H->setZero();
      g->setZero();
    }
    double total = 0.0;
    for (std::size_t k = 0; k < projections.size(); ++k) {
      Vec2 r;
      Eigen::Matrix<double, 2, 6> J_line;
      if (!projections[k].evaluateWith(terms[k], L, &r, nullptr, H != nullptr ? &J_line : nullptr))
        return std::numeric_limits<double>::infinity();
      double rho[3];
      loss.Evaluate(r.squaredNorm(), rho);
      total += 0.5 * rho[0];
      if (H == nullptr) continue;
      const Eigen::Matrix<double, 2, 4> J = J_line * plus;
      H->noalias() += rho[1] * J.transpose() * J;
      g->noalias() += rho[1] * J.transpose() * r;
    }
    return total;
  };
  constexpr double kFunctionTolerance = 1e-6;  // stop when a step lowers the cost by less than this share (Ceres' default)
  Vec6 L = *L_W;
  Eigen::Matrix4d H;
  Eigen::Vector4d g;
  double c = cost(L, &H, &g);
  // Damping mu relative to diag(H), updated as Ceres' Levenberg-Marquardt does (Nielsen 1999; initial trust region
  // radius 1e4).
  double mu = 1e-4, v = 2.0;
  for (int it = 0; it < options.max_iterations && std::isfinite(c); ++it) {
    const Eigen::Vector4d D = H.diagonal().cwiseMax(1e-6);
    Eigen::Matrix4d A = H;
    A.diagonal() += mu * D;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(A);
    if (ldlt.info() != Eigen::Success) break;
    const Eigen::Vector4d delta = ldlt.solve(-g);
    if (!delta.allFinite()) break;
    Vec6 trial;
    manifold.Plus(L.data(), delta.data(), trial.data());
    const double c_trial = cost(trial, nullptr, nullptr);
    // Decrease of the undamped model: with (H + mu D) delta = -g it is 0.5 (mu delta' D delta - g' delta).
    const double model = 0.5 * (mu * delta.dot(D.cwiseProduct(delta)) - g.dot(delta));
    const double rho = (c - c_trial) / model;
    if (!(c_trial < c) || !(model > 0.0) || !(rho > 1e-3)) {
      mu *= v;
      v *= 2.0;
      continue;
    }
    const double relative = (c - c_trial) / std::max(c, std::numeric_limits<double>::min());
    L = trial;
    mu *= std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3));
    v = 2.0;
    if (relative < kFunctionTolerance) break;
    c = cost(L, &H, &g);
  }

  const Vec6 refined = L;
  if (!refined.allFinite() || !(meanSightingErrorPx(refined, sightings, options.focal_px) < before)) return false;
  *L_W = refined;
  return true;
}

double lineEndpointSigmaM(const Vec6& L_W, const std::vector<LineSighting>& sightings, const Vec3& a, const Vec3& b,
                          double focal_px, double pixel_sigma) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  if (sightings.size() < 2 || !L_W.allFinite() || !(pixel_sigma > 0.0)) return kInf;
  const LineManifold manifold;
  Eigen::Matrix<double, kLineAmbientSize, kLineTangentSize, Eigen::RowMajor> plus;
  manifold.PlusJacobian(L_W.data(), plus.data());
  // Information of the line's tangent coordinates from the whitened endpoint distances.
  Eigen::Matrix4d info = Eigen::Matrix4d::Zero();
  for (const LineSighting& o : sightings) {
    // The sighting's camera is the factor's body (identity extrinsics).
    const LineProjection f(o.s, o.e, Pose(), focal_px / pixel_sigma);
    Vec2 r;
    Eigen::Matrix<double, 2, 6> J_line;
    if (!f.evaluate(o.T_W_C, L_W, &r, nullptr, &J_line)) continue;
    const Eigen::Matrix<double, 2, 4> J = J_line * plus;
    info.noalias() += J.transpose() * J;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(info);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues()(0) > 1e-12 * std::max(1.0, eig.eigenvalues()(3))))
    return kInf;
  const Eigen::Matrix4d cov = eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() *
                              eig.eigenvectors().transpose();
  // An endpoint x is carried by the line as its foot q(L) = p0 + ((x - p0) . d) d; its displacement across the line
  // (I - d d^T) dq / d(delta) by central differences along each tangent direction.
  const auto foot = [](const Vec6& L, const Vec3& x) {
    const Vec3 d = pluckerDirection(L), p0 = pluckerClosestPointToOrigin(L);
    return Vec3(p0 + (x - p0).dot(d) * d);
  };
  const Vec3 d0 = pluckerDirection(L_W);
  const Mat3 across = Mat3::Identity() - d0 * d0.transpose();
  constexpr double kStep = 1e-6;
  double worst = 0.0;
  for (const Vec3* x : {&a, &b}) {
    Eigen::Matrix<double, 3, 4> D;
    for (int k = 0; k < kLineTangentSize; ++k) {
      Eigen::Vector4d delta = Eigen::Vector4d::Zero();
      Vec6 plus_L, minus_L;
      delta(k) = kStep;
      manifold.Plus(L_W.data(), delta.data(), plus_L.data());
      delta(k) = -kStep;
      manifold.Plus(L_W.data(), delta.data(), minus_L.data());
      D.col(k) = across * (foot(plus_L, *x) - foot(minus_L, *x)) / (2.0 * kStep);
    }
    worst = std::max(worst, (D * cov * D.transpose()).trace());
  }
  return std::isfinite(worst) ? std::sqrt(worst) : kInf;
}

}  // namespace linnet
