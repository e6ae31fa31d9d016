// Plücker lines (plucker.h): transforms against transformed points, distances, the orthonormal representation,
// back-projection planes and their intersection, the ray-line closest point and the endpoint distances, all
// against direct constructions from points.
#include "linnet/geometry/plucker.h"

#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

namespace linnet {
namespace {

Pose randomPose(std::mt19937& rng, double spread) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose(expSO3(Vec3(n(rng), n(rng), n(rng))), spread * Vec3(n(rng), n(rng), n(rng)));
}

Vec3 randomVec(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  return scale * Vec3(n(rng), n(rng), n(rng));
}

/// Normalised image coordinates of a W point seen from camera T_W_C.
Vec2 project(const Pose& T_W_C, const Vec3& p_W) {
  const Vec3 p_C = T_W_C.inverse() * p_W;
  return p_C.head<2>() / p_C.z();
}

/// A camera at c looking at `target` (z axis towards it).
Pose lookAt(const Vec3& c, const Vec3& target) {
  const Vec3 z = (target - c).normalized();
  const Vec3 x = Vec3::UnitY().cross(z).normalized();
  Mat3 R;
  R << x, z.cross(x), z;
  return Pose(R, c);
}

TEST(Plucker, TransformMatchesTransformedPoints) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < 20; ++trial) {
    const Pose T = randomPose(rng, 3.0);
    const Vec3 a = randomVec(rng, 2.0), b = randomVec(rng, 2.0);
    const Vec6 L = pluckerFromPoints(a, b);
    // Definition: n = a x b, v = b - a.
    EXPECT_EQ(L.head<3>(), a.cross(b));
    EXPECT_EQ(L.tail<3>(), b - a);
    EXPECT_NEAR(L.head<3>().dot(L.tail<3>()), 0.0, 1e-12);  // Klein constraint
    // Same scale: (R a + t) x (R b + t) = R (a x b) + t x R (b - a).
    const Vec6 expected = pluckerFromPoints(T * a, T * b);
    const Vec6 got = transformPlucker(T, L);
    EXPECT_LT((got - expected).norm(), 1e-12 * (1.0 + expected.norm())) << trial;
    EXPECT_LT((pluckerTransformMatrix(T) * L - got).norm(), 1e-12 * (1.0 + expected.norm())) << trial;
    // Round trip through the inverse, and the matrix of the inverse is the inverse matrix.
    EXPECT_LT((transformPlucker(T.inverse(), got) - L).norm(), 1e-11 * (1.0 + L.norm()));
    EXPECT_LT((pluckerTransformMatrix(T.inverse()) * pluckerTransformMatrix(T) - Mat6::Identity()).norm(), 1e-12);
  }
}

TEST(Plucker, DistancesAndClosestPoint) {
  const Vec3 d = Vec3(1.0, -2.0, 0.5).normalized();
  const Vec3 p0(0.3, 1.2, 2.0);
  const Vec3 foot = p0 - p0.dot(d) * d;  // the line's point closest to the origin
  for (const double scale : {1.0, -2.5, 1e-3}) {
    const Vec6 L = scale * pluckerFromPoints(p0 - 0.7 * d, p0 + 1.9 * d);
    EXPECT_LT((pluckerClosestPointToOrigin(L) - foot).norm(), 1e-12) << scale;
    EXPECT_NEAR(pluckerDistanceToOrigin(L), foot.norm(), 1e-12) << scale;
    EXPECT_NEAR(std::abs(pluckerDirection(L).dot(d)), 1.0, 1e-15) << scale;
    EXPECT_GT(pluckerDirection(L).dot(d) * scale, 0.0);  // direction follows v's sign
    // A point at distance 0.4 from the line, off the foot.
    const Vec3 perp = d.cross(Vec3::UnitZ()).normalized();
    EXPECT_NEAR(pluckerPointDistance(L, p0 + 3.0 * d + 0.4 * perp), 0.4, 1e-12) << scale;
    EXPECT_NEAR(pluckerPointDistance(L, foot), 0.0, 1e-12);
  }
}

TEST(Plucker, OrthonormalRoundTripUpToScale) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < 20; ++trial) {
    const Vec3 a = randomVec(rng, 3.0), b = randomVec(rng, 3.0);
    const double scale = trial % 2 == 0 ? 3.7 : -0.2;
    const Vec6 L = scale * pluckerFromPoints(a, b);
    const OrthonormalLine o = toOrthonormal(L);
    EXPECT_LT((o.U.transpose() * o.U - Mat3::Identity()).norm(), 1e-12);
    EXPECT_NEAR(o.U.determinant(), 1.0, 1e-12);
    EXPECT_NEAR(o.w.norm(), 1.0, 1e-14);
    EXPECT_GE(o.w.x(), 0.0);
    EXPECT_GE(o.w.y(), 0.0);
    EXPECT_NEAR(o.w.x() / o.w.y(), pluckerDistanceToOrigin(L), 1e-12 * (1.0 + pluckerDistanceToOrigin(L)));
    const Vec6 back = fromOrthonormal(o);
    EXPECT_NEAR(back.norm(), 1.0, 1e-14);
    EXPECT_LT((back - L / L.norm()).norm(), 1e-12) << trial;  // same line, same sign, unit norm
    EXPECT_LT((normalisePlucker(L) - back).norm(), 1e-15);
    // And again: the representation of a unit line is a fixed point.
    EXPECT_LT((fromOrthonormal(toOrthonormal(back)) - back).norm(), 1e-14);
  }
  // A line through the origin: w1 = 0, U still a rotation, L = (0, v / |v|).
  const Vec6 L0 = pluckerFromPoints(Vec3(1, 2, 3), Vec3(2, 4, 6));
  EXPECT_LT(L0.head<3>().norm(), 1e-15);
  const OrthonormalLine o0 = toOrthonormal(L0);
  EXPECT_LT((o0.U.transpose() * o0.U - Mat3::Identity()).norm(), 1e-12);
  EXPECT_NEAR(o0.U.determinant(), 1.0, 1e-12);
  EXPECT_EQ(o0.w.x(), 0.0);
  EXPECT_LT((fromOrthonormal(o0).tail<3>() - Vec3(1, 2, 3).normalized()).norm(), 1e-15);
  // A Plücker vector off the Klein quadric is projected onto it (n made orthogonal to v).
  Vec6 off = pluckerFromPoints(Vec3(1, 0, 2), Vec3(0, 1, 2));
  off.head<3>() += 0.1 * off.tail<3>();
  const Vec6 fixed = normalisePlucker(off);
  EXPECT_NEAR(fixed.head<3>().dot(fixed.tail<3>()), 0.0, 1e-15);
  EXPECT_LT((pluckerClosestPointToOrigin(fixed) - pluckerClosestPointToOrigin(pluckerFromPoints(
                                                      Vec3(1, 0, 2), Vec3(0, 1, 2)))).norm(), 1e-12);
}

TEST(Plucker, BackProjectionPlanesIntersectInTheLine) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    // A segment 3-6 m ahead of two cameras 0.1-1 m apart, both looking at it.
    const Vec3 mid(u(rng), u(rng), 4.5 + 1.5 * u(rng));
    const Vec3 A = mid + Vec3(u(rng), 1.0 + 0.5 * u(rng), 0.5 * u(rng));
    const Vec3 B = mid - Vec3(u(rng), 1.0 + 0.5 * u(rng), 0.5 * u(rng));
    const Vec3 c1 = 0.5 * Vec3(u(rng), u(rng), u(rng));
    const Vec3 c2 = c1 + Vec3(0.1 + 0.9 * std::abs(u(rng)), 0.2 * u(rng), 0.2 * u(rng));
    const Pose T1 = lookAt(c1, mid), T2 = lookAt(c2, mid + Vec3(0.2, 0.0, 0.0));
    const Eigen::Vector4d p1 = backProjectionPlane(T1, project(T1, A), project(T1, B));
    const Eigen::Vector4d p2 = backProjectionPlane(T2, project(T2, A), project(T2, B));
    // Unit normals; every plane holds its camera centre and both endpoints.
    for (const Eigen::Vector4d* p : {&p1, &p2}) {
      EXPECT_NEAR(p->head<3>().norm(), 1.0, 1e-14);
      for (const Vec3& X : {A, B}) EXPECT_NEAR(p->head<3>().dot(X) + (*p)(3), 0.0, 1e-12);
    }
    EXPECT_NEAR(p1.head<3>().dot(c1) + p1(3), 0.0, 1e-12);
    EXPECT_NEAR(p2.head<3>().dot(c2) + p2(3), 0.0, 1e-12);

    double sin_angle = -1.0;
    const Vec6 L = intersectPlanes(p1, p2, &sin_angle);
    const Vec3 v = L.tail<3>();
    EXPECT_LT(pluckerDirection(L).cross((B - A).normalized()).norm(), 1e-9) << trial;
    EXPECT_LT(pluckerPointDistance(L, A), 1e-9) << trial;
    EXPECT_LT(pluckerPointDistance(L, B), 1e-9) << trial;
    // The moment follows the convention n = P x v for the points P of the line (not just up to sign).
    EXPECT_LT((L.head<3>() - A.cross(v)).norm(), 1e-9 * v.norm()) << trial;
    EXPECT_LT((L.head<3>() - B.cross(v)).norm(), 1e-9 * v.norm()) << trial;
    const Vec3 u_true = (B - A).normalized();
    const Vec3 foot = A - A.dot(u_true) * u_true;
    EXPECT_LT((pluckerClosestPointToOrigin(L) - foot).norm(), 1e-9) << trial;
    // The sine of the angle between the planes, from the normals built directly from the points.
    const Vec3 m1 = (A - c1).cross(B - c1).normalized(), m2 = (A - c2).cross(B - c2).normalized();
    EXPECT_NEAR(sin_angle, m1.cross(m2).norm(), 1e-12) << trial;
    EXPECT_GT(sin_angle, 0.0);
    // Scaled planes: same line, same angle.
    double sin_scaled = -1.0;
    const Vec6 Ls = intersectPlanes(3.0 * p1, -0.5 * p2, &sin_scaled);
    EXPECT_NEAR(sin_scaled, sin_angle, 1e-12);
    EXPECT_LT(pluckerPointDistance(Ls, A) + pluckerPointDistance(Ls, B), 1e-9);
    // nullptr for the angle is allowed.
    EXPECT_LT((intersectPlanes(p1, p2) - L).norm(), 1e-15);
  }
}

TEST(Plucker, ParallelPlanesHaveZeroAngle) {
  // The two cameras and the line in one plane (line parallel to the baseline): identical planes, sine 0.
  const Vec3 A(-1.0, 0.5, 4.0), B(1.0, 0.5, 4.0);
  const Pose T1(Quat::Identity(), Vec3::Zero()), T2(Quat::Identity(), Vec3(0.11, 0.0, 0.0));
  double sin_angle = -1.0;
  const Vec6 L = intersectPlanes(backProjectionPlane(T1, project(T1, A), project(T1, B)),
                                 backProjectionPlane(T2, project(T2, A), project(T2, B)), &sin_angle);
  EXPECT_LT(sin_angle, 1e-12);
  EXPECT_LT(L.tail<3>().norm(), 1e-12);
}

TEST(Plucker, ClosestPointToRay) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    const Pose T_W_C = randomPose(rng, 2.0);
    // A line through X (depth 2-6 m in the camera) with a direction far from the viewing ray.
    const Vec3 X_C(0.5 * u(rng), 0.5 * u(rng), 4.0 + 2.0 * u(rng));
    const Vec3 X = T_W_C * X_C;
    const Vec3 dir = T_W_C.q * Vec3(1.0, 0.3 * u(rng), 0.2 * u(rng)).normalized();
    const Vec6 L = -1.7 * pluckerFromPoints(X - 0.8 * dir, X + 1.3 * dir);
    const Vec2 x = X_C.head<2>() / X_C.z();
    const Vec3 ray = T_W_C.q * Vec3(x.x(), x.y(), 1.0);
    const std::optional<RayLinePoint> p = closestPointToRay(L, T_W_C.p, ray);
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(p->ray_t, X_C.z(), 1e-9) << trial;  // the camera depth of X
    EXPECT_LT((p->on_line - X).norm(), 1e-9) << trial;
    // A ray that misses the line by 0.2 m (offset along the common perpendicular): the closest points are the
    // ends of that perpendicular.
    const Vec3 perp = dir.cross(ray).normalized();
    const Vec3 Y = X + 0.2 * perp;
    const std::optional<RayLinePoint> q = closestPointToRay(L, T_W_C.p, Y - T_W_C.p);
    ASSERT_TRUE(q.has_value());
    const Vec3 on_ray = T_W_C.p + q->ray_t * (Y - T_W_C.p);
    EXPECT_NEAR(pluckerPointDistance(L, q->on_line), 0.0, 1e-9);
    EXPECT_NEAR((on_ray - q->on_line).dot(dir), 0.0, 1e-9);
    EXPECT_NEAR((on_ray - q->on_line).dot(Y - T_W_C.p), 0.0, 1e-9);
  }
  // A ray parallel to the line: no closest point.
  const Vec6 L = pluckerFromPoints(Vec3(0, 1, 0), Vec3(0, 1, 5));
  EXPECT_FALSE(closestPointToRay(L, Vec3::Zero(), Vec3(0, 0, 2)).has_value());
  // A point behind the camera gives a negative ray parameter.
  const Vec6 M = pluckerFromPoints(Vec3(-1, 0, -3), Vec3(1, 0, -3));
  const std::optional<RayLinePoint> behind = closestPointToRay(M, Vec3::Zero(), Vec3(0, 0, 1));
  ASSERT_TRUE(behind.has_value());
  EXPECT_NEAR(behind->ray_t, -3.0, 1e-12);
}

TEST(Plucker, LineEndpointDistances) {
  // l = (3, 4, -5): |(l1, l2)| = 5. s = (1, 1): (3 + 4 - 5) / 5 = 0.4; e = (-1, 2): (-3 + 8 - 5) / 5 = 0.
  const Vec2 d = lineEndpointDistances(Vec3(3.0, 4.0, -5.0), Vec2(1.0, 1.0), Vec2(-1.0, 2.0));
  EXPECT_NEAR(d.x(), 0.4, 1e-15);
  EXPECT_NEAR(d.y(), 0.0, 1e-15);
  // Signed, and invariant to the scale of l (up to its sign): (-6 - 8 + 10) / 10, (0 + 0 + 10) / 10.
  const Vec2 d2 = lineEndpointDistances(Vec3(-6.0, -8.0, 10.0), Vec2(1.0, 1.0), Vec2(0.0, 0.0));
  EXPECT_NEAR(d2.x(), -0.4, 1e-15);
  EXPECT_NEAR(d2.y(), 1.0, 1e-15);
  // The image line of a 3D line (n_C) against the projections: an endpoint 0.01 off the line, perpendicular.
  const Vec3 A(-0.5, 0.2, 3.0), B(0.7, -0.1, 4.0);
  const Vec3 l = pluckerFromPoints(A, B).head<3>();
  const Vec2 a = A.head<2>() / A.z(), b = B.head<2>() / B.z();
  const Vec2 normal = Vec2(l.x(), l.y()).normalized();
  const Vec2 dist = lineEndpointDistances(l, a + 0.01 * normal, b);
  EXPECT_NEAR(dist.x(), 0.01, 1e-14);
  EXPECT_NEAR(dist.y(), 0.0, 1e-14);
  // A line through the camera centre projects to a point: infinite distances.
  const Vec2 inf = lineEndpointDistances(Vec3(0.0, 0.0, 1.0), Vec2(0.1, 0.2), Vec2(0.3, 0.4));
  EXPECT_EQ(inf.x(), std::numeric_limits<double>::infinity());
  EXPECT_EQ(inf.y(), std::numeric_limits<double>::infinity());
}

}  // namespace
}  // namespace linnet
