// Plücker lines (see plucker.h for the conventions and references).
#include "linnet/geometry/plucker.h"

#include <cmath>
#include <limits>

namespace linnet {

Vec6 pluckerFromPoints(const Vec3& a, const Vec3& b) {
  Vec6 L;
  L << a.cross(b), b - a;
  return L;
}

Mat6 pluckerTransformMatrix(const Pose& T_A_B) {
  const Mat3 R = T_A_B.R();
  Mat6 M = Mat6::Zero();
  M.topLeftCorner<3, 3>() = R;
  M.topRightCorner<3, 3>() = skew(T_A_B.p) * R;
  M.bottomRightCorner<3, 3>() = R;
  return M;
}

Vec6 transformPlucker(const Pose& T_A_B, const Vec6& L_B) {
  const Mat3 R = T_A_B.R();
  const Vec3 v = R * L_B.tail<3>();
  Vec6 L;
  L << R * L_B.head<3>() + T_A_B.p.cross(v), v;
  return L;
}

Vec3 pluckerDirection(const Vec6& L) { return L.tail<3>().normalized(); }

Vec3 pluckerClosestPointToOrigin(const Vec6& L) {
  const Vec3 n = L.head<3>(), v = L.tail<3>();
  return v.cross(n) / v.squaredNorm();
}

double pluckerDistanceToOrigin(const Vec6& L) { return L.head<3>().norm() / L.tail<3>().norm(); }

double pluckerPointDistance(const Vec6& L, const Vec3& x) {
  const Vec3 n = L.head<3>(), v = L.tail<3>();
  return (x.cross(v) - n).norm() / v.norm();
}

Vec6 normalisePlucker(const Vec6& L) { return fromOrthonormal(toOrthonormal(L)); }

OrthonormalLine toOrthonormal(const Vec6& L) {
  Vec3 n = L.head<3>();
  const Vec3 v = L.tail<3>();
  const double v_norm = v.norm();
  const Vec3 u2 = v / v_norm;
  n -= n.dot(u2) * u2;  // Klein constraint, exactly
  const double n_norm = n.norm();
  Vec3 u1;
  if (n_norm > 1e-12 * std::max(1.0, v_norm)) {
    u1 = n / n_norm;
  } else {
    // Through the origin: any direction orthogonal to v (the representation's w1 = 0 makes it irrelevant to L).
    const Vec3 helper = std::abs(u2.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
    u1 = helper.cross(u2).normalized();
  }
  OrthonormalLine o;
  o.U.col(0) = u1;
  o.U.col(1) = u2;
  o.U.col(2) = u1.cross(u2);
  const double s = std::sqrt(n_norm * n_norm + v_norm * v_norm);
  o.w = Vec2(n_norm / s, v_norm / s);
  return o;
}

Vec6 fromOrthonormal(const OrthonormalLine& o) {
  Vec6 L;
  L << o.w.x() * o.U.col(0), o.w.y() * o.U.col(1);
  return L;
}

Vec2 lineEndpointDistances(const Vec3& l, const Vec2& s, const Vec2& e) {
  const double norm = std::hypot(l.x(), l.y());
  if (!(norm > 0.0)) return Vec2::Constant(std::numeric_limits<double>::infinity());
  return Vec2(s.x() * l.x() + s.y() * l.y() + l.z(), e.x() * l.x() + e.y() * l.y() + l.z()) / norm;
}

Eigen::Vector4d backProjectionPlane(const Pose& T_W_C, const Vec2& s, const Vec2& e) {
  const Vec3 m = Vec3(s.x(), s.y(), 1.0).cross(Vec3(e.x(), e.y(), 1.0));
  const Vec3 a = T_W_C.q * m.normalized();
  Eigen::Vector4d plane;
  plane << a, -a.dot(T_W_C.p);
  return plane;
}

Vec6 intersectPlanes(const Eigen::Vector4d& p1, const Eigen::Vector4d& p2, double* sin_angle) {
  const Vec3 a1 = p1.head<3>(), a2 = p2.head<3>();
  const double d1 = p1(3), d2 = p2(3);
  Vec6 L;
  L << d1 * a2 - d2 * a1, a1.cross(a2);
  if (sin_angle != nullptr) *sin_angle = L.tail<3>().norm() / (a1.norm() * a2.norm());
  return L;
}

std::optional<RayLinePoint> closestPointToRay(const Vec6& L, const Vec3& c, const Vec3& r) {
  // Line: X = P0 + s u (unit u); ray: Y = c + t r. Minimise |P0 + s u - c - t r|^2 over (s, t).
  const Vec3 u = pluckerDirection(L);
  const Vec3 P0 = pluckerClosestPointToOrigin(L);
  const Vec3 w0 = P0 - c;
  const double a = 1.0, b = u.dot(r), cc = r.dot(r), d = u.dot(w0), e = r.dot(w0);
  const double den = a * cc - b * b;
  if (!(den > 1e-12 * cc)) return std::nullopt;
  const double s = (b * e - cc * d) / den;
  const double t = (a * e - b * d) / den;
  RayLinePoint out;
  out.ray_t = t;
  out.on_line = P0 + s * u;
  if (!out.on_line.allFinite() || !std::isfinite(t)) return std::nullopt;
  return out;
}

}  // namespace linnet
