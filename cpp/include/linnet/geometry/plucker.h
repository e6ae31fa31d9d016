// 3D lines in Plücker coordinates and their orthonormal representation (DESIGN B1 "Line parameterisation"; thesis
// ch. 4; Bartoli & Sturm, "Structure-from-motion using lines: representation, triangulation and bundle adjustment",
// CVIU 2005).
//
// A line L = (n, v): v is its direction, n = P x v the moment for any point P on it (for two points P1, P2:
// n = P1 x P2, v = P2 - P1). L is homogeneous (L ~ s L, s != 0) and satisfies the Klein constraint n . v = 0, so it
// has 4 degrees of freedom. Its distance to the origin is |n| / |v|.
//
// Transform: L_A = T_A_B L_B with n_A = R n_B + [t]x R v_B, v_A = R v_B (T_A_B = (R, t)).
// Projection into a camera, in normalised image coordinates: the image line is l = n_C (l . (x, y, 1) = 0 for the
// points of the projected line).
//
// Orthonormal representation: U = [n/|n|, v/|v|, (n x v)/|n x v|] in SO(3) and W = [[w1, -w2], [w2, w1]] in SO(2)
// with (w1, w2) = (|n|, |v|) / sqrt(|n|^2 + |v|^2); L = (w1 u1, w2 u2) (unit norm). The update used by the estimator's
// manifold is U <- U Exp(dpsi), W <- W R(dphi) (4 DoF).
#pragma once

#include <optional>

#include <Eigen/Core>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat6 = Eigen::Matrix<double, 6, 6>;

/// Plücker coordinates [n; v] of the line through two points (homogeneous w = 1): n = a x b, v = b - a.
Vec6 pluckerFromPoints(const Vec3& a, const Vec3& b);

/// The 6x6 matrix [[R, [t]x R], [0, R]] with L_A = M L_B for T_A_B = (R, t).
Mat6 pluckerTransformMatrix(const Pose& T_A_B);
/// L_A = T_A_B L_B.
Vec6 transformPlucker(const Pose& T_A_B, const Vec6& L_B);

/// Direction v / |v|.
Vec3 pluckerDirection(const Vec6& L);
/// Point of the line closest to the origin: (v x n) / |v|^2.
Vec3 pluckerClosestPointToOrigin(const Vec6& L);
/// Distance of the line to the origin |n| / |v|.
double pluckerDistanceToOrigin(const Vec6& L);
/// Distance of a point to the line: |x x v - n| / |v|.
double pluckerPointDistance(const Vec6& L, const Vec3& x);
/// L scaled to |L| = 1 (the orthonormal representation's scale), with n made exactly orthogonal to v.
Vec6 normalisePlucker(const Vec6& L);

/// The orthonormal representation of a line.
struct OrthonormalLine {
  Mat3 U = Mat3::Identity();    // [u1 u2 u3], a rotation
  Vec2 w = Vec2(1.0, 0.0);      // (w1, w2) = (cos phi, sin phi), w1, w2 >= 0 for lines from toOrthonormal
};
/// U and W of L. If n = 0 (a line through the origin), u1 is any unit vector orthogonal to v.
OrthonormalLine toOrthonormal(const Vec6& L);
/// L = (w1 u1, w2 u2), unit norm.
Vec6 fromOrthonormal(const OrthonormalLine& o);

/// Distances of the endpoints s, e (normalised image coordinates) to the image line l (normalised coordinates):
/// (s . l, e . l) / |(l1, l2)| with s, e homogenised. Infinite if l is (0, 0, *).
Vec2 lineEndpointDistances(const Vec3& l, const Vec2& s, const Vec2& e);

/// The back-projection plane of an image segment (normalised coordinates s, e) seen from camera T_W_C, in W:
/// a . X + d = 0 with a = R (s x e) / |s x e| (s, e homogenised) and d = -a . c for the camera centre c.
Eigen::Vector4d backProjectionPlane(const Pose& T_W_C, const Vec2& s, const Vec2& e);

/// Intersection of two planes (a1, d1), (a2, d2): L = (d1 a2 - d2 a1, a1 x a2). `sin_angle` (may be nullptr) gets
/// the sine of the angle between the planes (|a1 x a2| for unit normals).
Vec6 intersectPlanes(const Eigen::Vector4d& p1, const Eigen::Vector4d& p2, double* sin_angle = nullptr);

/// Point of the line L (in W) closest to the viewing ray from centre c with direction r (in W), as the parameter
/// along the ray (depth along r, with r not normalised: r = R_W_C (x, y, 1) gives the camera depth) and the 3D point.
/// nullopt if the ray is parallel to the line.
struct RayLinePoint {
  double ray_t = 0.0;  // X = c + ray_t r on the ray (closest to the line)
  Vec3 on_line = Vec3::Zero();  // the line's point closest to the ray
};
std::optional<RayLinePoint> closestPointToRay(const Vec6& L, const Vec3& c, const Vec3& r);

}  // namespace linnet
