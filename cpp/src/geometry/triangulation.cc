// Point triangulation: DLT (Hartley & Zisserman, MVG 2nd ed., sec. 12.2), ray parallax, depth checks and a
// small Gauss-Newton refinement in normalised image coordinates.
#include "linnet/geometry/triangulation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include <Eigen/Dense>

#include "linnet/core/error.h"

namespace linnet {
namespace {

constexpr double kRadPerDeg = 3.14159265358979323846 / 180.0;

/// Residual of one view (projection - observation) and its Jacobian w.r.t. p_W. Returns false if behind the
/// camera.
bool viewResidual(const Pose& T_W_C, const Vec2& uv, const Vec3& p_W, Vec2* r,
                  Eigen::Matrix<double, 2, 3>* J) {
  const Mat3 R_C_W = T_W_C.R().transpose();
  const Vec3 p_C = R_C_W * (p_W - T_W_C.p);
  if (!(p_C.z() > 1e-9)) return false;
  const double iz = 1.0 / p_C.z();
  *r = Vec2(p_C.x() * iz, p_C.y() * iz) - uv;
  if (J != nullptr) {
    Eigen::Matrix<double, 2, 3> d_proj;
    d_proj << iz, 0.0, -p_C.x() * iz * iz, 0.0, iz, -p_C.y() * iz * iz;
    *J = d_proj * R_C_W;
  }
  return true;
}

double sumSquaredError(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, const Vec3& p_W) {
  double sum = 0.0;
  for (std::size_t k = 0; k < T_W_C.size(); ++k) {
    Vec2 r;
    if (!viewResidual(T_W_C[k], uv[k], p_W, &r, nullptr)) return std::numeric_limits<double>::infinity();
    sum += r.squaredNorm();
  }
  return sum;
}

void requireSameSize(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, const char* who) {
  if (T_W_C.size() != uv.size())
    throw UsageError(std::string(who) + ": " + std::to_string(T_W_C.size()) + " poses but " +
                     std::to_string(uv.size()) + " observations");
}

}  // namespace

const char* toString(TriangulationStatus s) {
  switch (s) {
    case TriangulationStatus::kOk:
      return "ok";
    case TriangulationStatus::kTooFewViews:
      return "too few views";
    case TriangulationStatus::kDegenerate:
      return "degenerate";
    case TriangulationStatus::kLowParallax:
      return "low parallax";
    case TriangulationStatus::kBadDepth:
      return "bad depth";
    case TriangulationStatus::kHighError:
      return "high reprojection error";
  }
  return "unknown";
}

bool triangulateDlt(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, Vec3* p_W) {
  requireSameSize(T_W_C, uv, "triangulateDlt");
  const std::size_t n = T_W_C.size();
  if (n < 2) return false;
  // Each view gives u * P.row(2) - P.row(0) and v * P.row(2) - P.row(1), with P = [R_C_W | -R_C_W p_W_C].
  Eigen::MatrixXd A(2 * n, 4);
  for (std::size_t k = 0; k < n; ++k) {
    const Mat3 R_C_W = T_W_C[k].R().transpose();
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = R_C_W;
    P.col(3) = -R_C_W * T_W_C[k].p;
    Eigen::RowVector4d row_u = uv[k].x() * P.row(2) - P.row(0);
    Eigen::RowVector4d row_v = uv[k].y() * P.row(2) - P.row(1);
    // Unit rows weigh every view alike whatever the scale of its translation.
    const double nu = row_u.norm(), nv = row_v.norm();
    if (nu > 0.0) row_u /= nu;
    if (nv > 0.0) row_v /= nv;
    A.row(2 * k) = row_u;
    A.row(2 * k + 1) = row_v;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A, Eigen::ComputeFullV);
  const Vec4 X = svd.matrixV().col(3);
  if (!(std::abs(X(3)) > 1e-10)) return false;  // X has unit norm: the point is (nearly) at infinity
  const Vec3 p = X.head<3>() / X(3);
  if (!p.allFinite()) return false;
  *p_W = p;
  return true;
}

double rayParallaxRad(const Pose& T_W_C0, const Vec2& uv0, const Pose& T_W_C1, const Vec2& uv1) {
  const Vec3 f0 = T_W_C0.q * Vec3(uv0.x(), uv0.y(), 1.0);
  const Vec3 f1 = T_W_C1.q * Vec3(uv1.x(), uv1.y(), 1.0);
  // atan2 of |cross| and dot is accurate for small and large angles alike.
  return std::atan2(f0.cross(f1).norm(), f0.dot(f1));
}

bool triangulateTwoView(const Pose& T_W_C0, const Vec2& uv0, const Pose& T_W_C1, const Vec2& uv1, Vec3* p_W,
                        double* parallax_rad) {
  if (parallax_rad != nullptr) *parallax_rad = rayParallaxRad(T_W_C0, uv0, T_W_C1, uv1);
  return triangulateDlt({T_W_C0, T_W_C1}, {uv0, uv1}, p_W);
}

double maxParallaxRad(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv) {
  requireSameSize(T_W_C, uv, "maxParallaxRad");
  double best = 0.0;
  for (std::size_t a = 0; a < T_W_C.size(); ++a)
    for (std::size_t b = a + 1; b < T_W_C.size(); ++b)
      best = std::max(best, rayParallaxRad(T_W_C[a], uv[a], T_W_C[b], uv[b]));
  return best;
}

double depthInCamera(const Pose& T_W_C, const Vec3& p_W) {
  return (T_W_C.q.conjugate() * (p_W - T_W_C.p)).z();
}

bool allDepthsPositive(const std::vector<Pose>& T_W_C, const Vec3& p_W, double min_depth, double max_depth) {
  for (const Pose& T : T_W_C) {
    const double z = depthInCamera(T, p_W);
    if (!(z >= min_depth && z <= max_depth)) return false;
  }
  return true;
}

double meanReprojectionError(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, const Vec3& p_W) {
  requireSameSize(T_W_C, uv, "meanReprojectionError");
  if (T_W_C.empty()) return 0.0;
  double sum = 0.0;
  for (std::size_t k = 0; k < T_W_C.size(); ++k) {
    Vec2 r;
    if (!viewResidual(T_W_C[k], uv[k], p_W, &r, nullptr)) return std::numeric_limits<double>::infinity();
    sum += r.norm();
  }
  return sum / static_cast<double>(T_W_C.size());
}

bool refinePoint(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, Vec3* p_W, int max_iterations) {
  requireSameSize(T_W_C, uv, "refinePoint");
  Vec3 p = *p_W;
  double cost = sumSquaredError(T_W_C, uv, p);
  if (!std::isfinite(cost)) return false;
  for (int it = 0; it < max_iterations; ++it) {
    Mat3 H = Mat3::Zero();
    Vec3 g = Vec3::Zero();
    for (std::size_t k = 0; k < T_W_C.size(); ++k) {
      Vec2 r;
      Eigen::Matrix<double, 2, 3> J;
      viewResidual(T_W_C[k], uv[k], p, &r, &J);  // in front of every camera: cost is finite
      H += J.transpose() * J;
      g += J.transpose() * r;
    }
    const Eigen::LDLT<Mat3> ldlt(H);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 1e-15 * H.trace())) return it > 0;
    const Vec3 step = -ldlt.solve(g);
    const Vec3 candidate = p + step;
    const double new_cost = sumSquaredError(T_W_C, uv, candidate);
    if (!(new_cost < cost)) break;  // also rejects a step that crosses behind a camera
    p = candidate;
    cost = new_cost;
    if (step.norm() < 1e-10 * (1.0 + p.norm())) break;
  }
  *p_W = p;
  return true;
}

TriangulationStatus triangulateChecked(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv,
                                       const TriangulationOptions& options, Vec3* p_W) {
  requireSameSize(T_W_C, uv, "triangulateChecked");
  if (T_W_C.size() < 2) return TriangulationStatus::kTooFewViews;
  if (maxParallaxRad(T_W_C, uv) < options.min_parallax_deg * kRadPerDeg)
    return TriangulationStatus::kLowParallax;
  Vec3 p;
  if (!triangulateDlt(T_W_C, uv, &p)) return TriangulationStatus::kDegenerate;
  if (!allDepthsPositive(T_W_C, p, options.min_depth_m, options.max_depth_m))
    return TriangulationStatus::kBadDepth;
  if (options.refine_iterations > 0) {
    refinePoint(T_W_C, uv, &p, options.refine_iterations);
    if (!allDepthsPositive(T_W_C, p, options.min_depth_m, options.max_depth_m))
      return TriangulationStatus::kBadDepth;
  }
  if (meanReprojectionError(T_W_C, uv, p) > options.max_reprojection) return TriangulationStatus::kHighError;
  *p_W = p;
  return TriangulationStatus::kOk;
}

}  // namespace linnet
