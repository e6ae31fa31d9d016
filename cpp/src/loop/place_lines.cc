// Loop verification with points and lines (see place_matcher.h): low-texture keyframes keep too few 3D corners for
// a PnP, but dozens of tracked lines.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Cholesky>

#include "linnet/core/error.h"
#include "linnet/geometry/projection.h"
#include "linnet/loop/place_matcher.h"
#include "place_match_detail.h"

namespace linnet {

void describePlaceLines(const cv::Mat& left, const std::vector<LineObservation>& lines, const LbdOptions& lbd,
                        PlaceFeatures* f, const std::vector<LbdDescriptor>* given) {
  if (left.empty()) return;
  if (given != nullptr && given->size() != lines.size())
    throw UsageError("describePlaceLines: " + std::to_string(given->size()) + " descriptors given for " +
                     std::to_string(lines.size()) + " lines");
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const LineObservation& o = lines[i];
    f->line_ids.push_back(o.id);
    f->line_uv.push_back({o.s0, o.e0});
    f->line_desc.push_back(given != nullptr ? (*given)[i]
                                            : binarizeLbd(computeLbdFloat(left, lbd, LineSegment{o.ps0, o.pe0})));
    const Vec3 none = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    f->line_p_C.push_back({none, none});
  }
}

void setPlaceLines(const std::vector<MapLine>& window_lines, const Pose& T_W_C, PlaceFeatures* f) {
  const Pose T_C_W = T_W_C.inverse();
  const Vec3 none = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
  for (std::size_t i = 0; i < f->line_ids.size(); ++i) {
    f->line_p_C[i] = {none, none};
    const auto it = std::lower_bound(window_lines.begin(), window_lines.end(), f->line_ids[i],
                                     [](const MapLine& l, std::int64_t id) { return l.id < id; });
    if (it == window_lines.end() || it->id != f->line_ids[i]) continue;
    const Vec3 a = T_C_W * it->a, b = T_C_W * it->b;
    if (a.allFinite() && b.allFinite() && a.z() > 0.1 && b.z() > 0.1) f->line_p_C[i] = {a, b};
  }
}

namespace {

// One residual block of the refinement: a 3D point of `a` and its corner in `b` (2 rows: the reprojection error), or
// a 3D segment of `a` and the line through its match in `b` (2 rows: each end's distance to that line). Normalised
// image units.
struct Block {
  bool line = false;
  Vec3 X[2] = {Vec3::Zero(), Vec3::Zero()};
  Vec2 uv = Vec2::Zero();
  Vec3 l = Vec3::Zero();  // the image line, l0^2 + l1^2 = 1
};

// Residual (and Jacobian for the perturbation R <- exp(dtheta) R, t <- t + dt) of one block at (R, t).
bool evaluate(const Block& b, const Mat3& R, const Vec3& t, Vec2* r, Eigen::Matrix<double, 2, 6>* J) {
  for (int k = 0; k < (b.line ? 2 : 1); ++k) {
    const Vec3 RX = R * b.X[k];
    const Vec3 p = RX + t;
    if (!(p.z() > 1e-6)) return false;
    Eigen::Matrix<double, 3, 6> dp;
    dp << -skew(RX), Mat3::Identity();
    const Eigen::Matrix<double, 2, 6> Jp = projectionJacobian(p) * dp;
    const Vec2 uv = p.head<2>() / p.z();
    if (!b.line) {
      *r = uv - b.uv;
      *J = Jp;
      return true;
    }
    (*r)(k) = b.l.x() * uv.x() + b.l.y() * uv.y() + b.l.z();
    J->row(k) = b.l.head<2>().transpose() * Jp;
  }
  return true;
}

// The block's error for the inlier test: a point's reprojection distance, a line's larger end distance.
double blockError(const Block& b, const Vec2& r) { return b.line ? r.cwiseAbs().maxCoeff() : r.norm(); }

// Robust Gauss-Newton (Huber at `huber`) from (R, t) over the blocks flagged in `use`.
bool gaussNewton(const std::vector<Block>& blocks, const std::vector<char>& use, double huber, Mat3* R, Vec3* t) {
  constexpr int kIterations = 10;
  for (int it = 0; it < kIterations; ++it) {
    Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> g = Eigen::Matrix<double, 6, 1>::Zero();
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      if (!use[i]) continue;
      Vec2 r;
      Eigen::Matrix<double, 2, 6> J;
      if (!evaluate(blocks[i], *R, *t, &r, &J)) return false;
      const double e = r.norm();
      const double w = e <= huber ? 1.0 : huber / e;
      H.noalias() += w * J.transpose() * J;
      g.noalias() += w * J.transpose() * r;
    }
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> ldlt(H);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return false;
    const Eigen::Matrix<double, 6, 1> delta = -ldlt.solve(g);
    if (!delta.allFinite()) return false;
    *R = expSO3(Vec3(delta.head<3>())).toRotationMatrix() * *R;
    *t += delta.tail<3>();
    if (delta.norm() < 1e-10) break;
  }
  return true;
}

// a's 3D segments matched to b's lines near their projections by T_Cb_Ca: direction within the angle, both of b's
// ends within the radius of the projected line, overlapping along it; the closest LBD descriptor (distance bound,
// ratio to the second candidate); one segment per line of b.
void matchLinesGuided(const PlaceFeatures& a, const PlaceFeatures& b, const Pose& T_Cb_Ca,
                      const PlaceMatchOptions& options, std::vector<Block>* blocks) {
  const double radius = options.guided_radius_px / options.focal_px;
  const double cos_max = std::cos(options.line_max_angle_deg * M_PI / 180.0);
  std::vector<int> used(b.line_uv.size(), 0);
  for (std::size_t i = 0; i < a.line_p_C.size(); ++i) {
    const auto& P = a.line_p_C[i];
    if (!P[0].allFinite() || !P[1].allFinite()) continue;
    const Vec3 A = T_Cb_Ca * P[0], B = T_Cb_Ca * P[1];
    if (!(A.z() > 0.1) || !(B.z() > 0.1)) continue;
    const Vec2 a2 = A.head<2>() / A.z(), b2 = B.head<2>() / B.z();
    const double len = (b2 - a2).norm();
    if (!(len > 1e-6)) continue;
    const Vec2 d = (b2 - a2) / len, n(-d.y(), d.x());
    int best = -1;
    int d1 = std::numeric_limits<int>::max(), d2 = d1;
    for (std::size_t j = 0; j < b.line_uv.size(); ++j) {
      const Vec2& s = b.line_uv[j][0];
      const Vec2& e = b.line_uv[j][1];
      if ((e - s).norm() < 1e-9 || std::abs(d.dot((e - s).normalized())) < cos_max) continue;
      if (std::max(std::abs(n.dot(s - a2)), std::abs(n.dot(e - a2))) > radius) continue;
      const double ts = d.dot(s - a2), te = d.dot(e - a2);
      if (std::max(ts, te) <= 0.0 || std::min(ts, te) >= len) continue;
      const int h = hammingDistance(a.line_desc[i], b.line_desc[j]);
      if (h < d1) {
        d2 = d1;
        d1 = h;
        best = static_cast<int>(j);
      } else if (h < d2) {
        d2 = h;
      }
    }
    if (best < 0 || d1 > options.line_max_hamming) continue;
    if (d2 != std::numeric_limits<int>::max() && d1 > options.match_ratio * d2) continue;
    if (used[static_cast<std::size_t>(best)]++) continue;
    const Vec2& s = b.line_uv[static_cast<std::size_t>(best)][0];
    const Vec2& e = b.line_uv[static_cast<std::size_t>(best)][1];
    Block blk;
    blk.line = true;
    blk.X[0] = P[0];
    blk.X[1] = P[1];
    blk.l = Vec3(s.x(), s.y(), 1.0).cross(Vec3(e.x(), e.y(), 1.0));
    blk.l /= blk.l.head<2>().norm();
    blocks->push_back(blk);
  }
}

// a's 3D corners and segments against b's corners and lines, from the prior T_Cb_Ca; on success T_Cb_Ca.
PlaceMatch solveWithLines(const PlaceFeatures& a, const PlaceFeatures& b, const Pose& prior,
                          const PlaceMatchOptions& options) {
  PlaceMatch out;
  out.method = PlaceMatchMethod::kLines;
  std::vector<Block> blocks;
  std::vector<cv::Point3d> object;
  std::vector<cv::Point2d> image;
  if (!a.p_C.empty() && b.descriptors_2d.rows > 0) place_detail::matchGuided(a, b, prior, options, &object, &image);
  for (std::size_t i = 0; i < object.size(); ++i) {
    Block blk;
    blk.X[0] = Vec3(object[i].x, object[i].y, object[i].z);
    blk.uv = Vec2(image[i].x, image[i].y);
    blocks.push_back(blk);
  }
  matchLinesGuided(a, b, prior, options, &blocks);
  out.matches = static_cast<int>(blocks.size());
  if (out.matches < options.min_inliers) return out;
  const double gate = options.ransac_px / options.focal_px;
  Mat3 R = prior.R();
  Vec3 t = prior.p;
  // All blocks under the Huber loss, then again on those within twice the gate; the inliers are within the gate.
  std::vector<char> use(blocks.size(), 1);
  if (!gaussNewton(blocks, use, gate, &R, &t)) return out;
  const auto select = [&](double limit) {
    int count = 0;
    for (std::size_t i = 0; i < blocks.size(); ++i) {
      Vec2 r;
      Eigen::Matrix<double, 2, 6> J;
      use[i] = evaluate(blocks[i], R, t, &r, &J) && blockError(blocks[i], r) < limit;
      count += use[i];
    }
    return count;
  };
  if (select(2.0 * gate) < options.min_inliers || !gaussNewton(blocks, use, gate, &R, &t)) return out;
  out.inliers = select(gate);
  if (out.inliers < options.min_inliers || !gaussNewton(blocks, use, gate, &R, &t)) return out;
  // Covariance from the inliers' information and residual variance.
  Eigen::Matrix<double, 6, 6> H = Eigen::Matrix<double, 6, 6>::Zero();
  double sum_sq = 0.0;
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    if (!use[i]) continue;
    Vec2 r;
    Eigen::Matrix<double, 2, 6> J;
    if (!evaluate(blocks[i], R, t, &r, &J)) return out;
    H.noalias() += J.transpose() * J;
    sum_sq += r.squaredNorm();
  }
  if (!place_detail::covarianceFromInformation(H, sum_sq, static_cast<std::size_t>(out.inliers), &out.covariance))
    return out;
  out.T_Cold_Cnew = Pose(Quat(R).normalized(), t);  // T_Cb_Ca here
  out.ok = R.allFinite() && t.allFinite();
  return out;
}

}  // namespace

PlaceMatch matchPlacesWithLines(const PlaceFeatures& old_kf, const PlaceFeatures& new_kf,
                                const PlaceMatchOptions& options) {
  if (!options.prior_T_Cold_Cnew) return {};
  const PlaceMatch forward = solveWithLines(new_kf, old_kf, *options.prior_T_Cold_Cnew, options);
  if (forward.ok) return forward;
  PlaceMatch backward = solveWithLines(old_kf, new_kf, options.prior_T_Cold_Cnew->inverse(), options);
  if (backward.ok) return place_detail::inverted(backward);
  backward.matches = std::max(backward.matches, forward.matches);
  backward.inliers = std::max(backward.inliers, forward.inliers);
  return backward;
}

}  // namespace linnet
