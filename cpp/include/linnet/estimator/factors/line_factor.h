// The line residual of DESIGN B1 (thesis ch. 4, eqs. 4-33..4-40): distances of an observed segment's endpoints to
// the projection of a 3D line, in normalised image coordinates.
//
// The line is a Plücker block L_W = [n_W; v_W] (LineManifold, the orthonormal update). Seen from camera C of frame j
// (T_W_C = T_W_Bj T_B_C): L_C = T_C_W L_W, i.e. n_C = R_C_W (n_W - c x v_W) with c the camera centre in W; the image
// line in normalised coordinates is l = n_C, and
//     r = sqrt_info * [s^T l, e^T l] / sqrt(l1^2 + l2^2)      (s, e: observed endpoints, homogenised).
// Parameter blocks: pose T_W_Bj (7, PoseManifold), line (6, LineManifold). The Jacobians are analytic along the chain
// orthonormal -> Plücker W -> Plücker C -> image line -> residual: the factor returns d r / d L_W (ambient; Ceres and
// the Schur solver multiply by LineManifold's PlusJacobian, the orthonormal -> Plücker step) and the pose Jacobian in
// the tangent space [dp, dtheta] (as it is for the Schur solver, converted by tangentToAmbientPose() for Ceres).
#pragma once

#include <array>
#include <memory>

#include <ceres/sized_cost_function.h>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/estimator/factors/tangent_jacobians.h"

namespace linnet {

using Vec6 = Eigen::Matrix<double, 6, 1>;

/// The residual's arithmetic without the Ceres cost function around it (no heap allocation: the map refinement
/// evaluates it for every sighting of every line that leaves the window, at every iteration).
class LineProjection {
 public:
  /// s, e: endpoints observed in camera C (normalised, undistorted); T_B_C: that camera's extrinsics; sqrt_info:
  /// focal / sigma (sigma in pixels), optionally times a weight.
  LineProjection(const Vec2& s, const Vec2& e, const Pose& T_B_C, double sqrt_info);

  /// Residual, the tangent pose Jacobian (w.r.t. [dp, dtheta]) and the Jacobian w.r.t. the Plücker coordinates;
  /// outputs may be nullptr. False if the line projects to a point or the result is not finite.
  bool evaluate(const Pose& T_W_B, const Vec6& L_W, Vec2* residual, Eigen::Matrix<double, 2, 6>* J_pose,
                Eigen::Matrix<double, 2, 6>* J_line) const;

  /// The pose's share of the evaluation: R^T, p and the two 3 x 3 maps of the Plücker coordinates in W to the image
  /// line (M_n = R_C_B R^T, M_v = R_C_B K with K = -R^T [p]x - [t]x R^T).
  struct PoseTerms {
    std::array<double, 7> block{};  // the pose block they were computed from (kept by the factor's cache)
    Mat3 Rt;
    Vec3 p;
    Mat3 M_n, M_v;  // the image line l = M_n n_W + M_v v_W
    bool valid = false;
  };
  void poseTerms(const Pose& T_W_B, PoseTerms* terms) const;
  /// evaluate() with the pose's terms given.
  bool evaluateWith(const PoseTerms& terms, const Vec6& L_W, Vec2* residual, Eigen::Matrix<double, 2, 6>* J_pose,
                    Eigen::Matrix<double, 2, 6>* J_line) const;

 private:
  Vec3 s_, e_;  // homogenised endpoints
  Mat3 R_C_B_;  // the camera's extrinsics T_B_C: its rotation (transposed, converted from the quaternion once)
  Vec3 t_B_C_;  // and its position in B
  double sqrt_info_;
};

/// The pose terms of one camera of one frame, shared by the line factors of all the lines it sees: they depend only
/// on the pose block and the camera's extrinsics, so the first factor evaluated at a pose computes them for all the
/// others (a window has about 90 lines in each of 12 frame cameras).
struct SharedLinePoseTerms {
  explicit SharedLinePoseTerms(const Pose& T_B_C) : T_B_C(T_B_C) {}
  Pose T_B_C;  // the extrinsics of every factor that uses these terms (checked when a factor takes them)
  LineProjection::PoseTerms terms;
};

class LineReprojectionFactor : public ceres::SizedCostFunction<2, 7, 6>, public TangentJacobians {
 public:
  /// As LineProjection's. `shared` (optional): the pose terms of the factors of the same frame and camera; its
  /// extrinsics must be T_B_C (UsageError otherwise).
  LineReprojectionFactor(const Vec2& s, const Vec2& e, const Pose& T_B_C, double sqrt_info,
                         std::shared_ptr<SharedLinePoseTerms> shared = nullptr);
  /// As if constructed anew with these arguments (FactorPool).
  void reset(const Vec2& s, const Vec2& e, const Pose& T_B_C, double sqrt_info,
             std::shared_ptr<SharedLinePoseTerms> shared = nullptr);

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override;
  /// The pose Jacobian in the tangent space, the line's w.r.t. the Plücker coordinates (as Evaluate).
  bool evaluateTangentSpace(double const* const* parameters, double* residuals, double** jacobians) const override;

  /// LineProjection::evaluate.
  bool evaluate(const Pose& T_W_B, const Vec6& L_W, Vec2* residual, Eigen::Matrix<double, 2, 6>* J_pose,
                Eigen::Matrix<double, 2, 6>* J_line) const {
    return projection_.evaluate(T_W_B, L_W, residual, J_pose, J_line);
  }

 private:
  LineProjection projection_;
  // The window solver's line iterations evaluate each factor several times at one pose (only the line moves), so
  // evaluateTangentSpace keeps the last pose's terms: its own, or the frame camera's shared ones. Either cache makes
  // concurrent evaluations unsafe (of one factor, or of factors sharing terms); the window solves are
  // single-threaded.
  mutable LineProjection::PoseTerms cache_;
  std::shared_ptr<SharedLinePoseTerms> shared_;
};

/// Mean endpoint-to-line distance in pixels of one observation (focal_px times the normalised distances), +infinity
/// if the line projects to a point.
double lineReprojectionErrorPx(const Vec6& L_W, const Pose& T_W_C, const Vec2& s, const Vec2& e, double focal_px);
/// The same with the camera's world -> camera pose T_C_W (= T_W_C.inverse()) given.
double lineReprojectionErrorPxFromCw(const Vec6& L_W, const Pose& T_C_W, const Vec2& s, const Vec2& e,
                                     double focal_px);

}  // namespace linnet
