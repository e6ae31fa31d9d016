// Point landmarks of the sliding window: observations per frame, inverse depth anchored in the host frame's cam0
// (host = oldest window frame that observes the point; re-anchored when the host leaves the window), triangulation
// from stereo or several views, the three point residual kinds of the thesis (ch. 4) and outlier rejection.
//
// A second landmark kind (lines) follows the same shape: observe / triangulate / residuals / removeFrame /
// rejectOutliers, with its own keys (lineBlockKey) -- the estimator calls each kind in turn.
#pragma once

#include <algorithm>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/estimator/estimator_options.h"
#include "linnet/estimator/factor_pool.h"
#include "linnet/estimator/factors/point_factors.h"
#include "linnet/estimator/residual_spec.h"
#include "linnet/estimator/window.h"

namespace linnet {

struct PointFrameObs {
  Vec2 uv0 = Vec2::Zero();  // normalised, cam0
  bool has_right = false;
  Vec2 uv1 = Vec2::Zero();  // normalised, cam1
};

struct PointLandmark {
  std::int64_t id = -1;
  std::map<FrameId, PointFrameObs> obs;  // ordered by frame id = oldest first
  FrameId host = -1;                      // frame whose cam0 anchors the inverse depth
  double inv_depth = 0.0;                 // 1 / depth in the host's cam0, 1/m (a Ceres parameter block)
  bool triangulated = false;
  bool used = false;                      // took part in the last solve
};

class PointLandmarks {
 public:
  PointLandmarks(const SolverOptions& options, const Pose& T_B_C0, std::optional<Pose> T_B_C1);

  /// Records the frame's point observations (ids may be new or known).
  void observe(FrameId frame, const std::vector<PointObservation>& points);
  /// Triangulates every landmark that is not yet triangulated: stereo in its host frame if it has a right
  /// observation, else multi-view DLT over its cam0 observations with enough parallax. Depth-checked.
  /// Returns the number of newly triangulated landmarks.
  int triangulate(const Window& window);
  /// Residuals of the landmarks usable in a solve (triangulated, observed in >= 2 frames). Marks them used.
  /// If host_only >= 0, only the landmarks hosted in that frame (for marginalisation), without touching `used`.
  /// all_right: cam1 residuals in every observing frame whatever solver.right_residuals_all_frames says.
  /// frame_weight (may be empty): cost weight per observing frame (point / line weighting).
  std::vector<ResidualSpec> residuals(const Window& window, FrameId host_only = -1, bool all_right = false,
                                      const std::map<FrameId, double>& frame_weight = {});
  /// Ids of the landmarks hosted in `frame` that residuals(window, frame) covers.
  std::vector<std::int64_t> hostedUsable(FrameId frame) const;
  /// Drops the frame's observations. Landmarks hosted there are re-anchored to their next observing frame
  /// (the window must still contain both frames); landmarks left without observations are erased.
  void removeFrame(const Window& window, FrameId frame);
  /// Erases used landmarks with a mean reprojection error above options.outlier_px or a depth out of range.
  /// Returns how many were erased.
  int rejectOutliers(const Window& window);

  /// Triangulated landmarks observed in `frame`.
  int countTriangulatedIn(FrameId frame) const;
  /// Landmarks that took part in the last solve.
  int countUsed() const;
  /// Landmarks observed in `frame` (triangulated or not).
  int countObservedIn(FrameId frame) const;
  /// Pairs (uv0 in frame a, uv0 in frame b) of the landmarks seen in both frames.
  std::vector<std::pair<Vec2, Vec2>> correspondences(FrameId a, FrameId b) const;
  /// Triangulated landmarks observed in `frame` and hosted by another frame: world positions and that frame's cam0
  /// observation.
  void triangulatedIn(const Window& window, FrameId frame, std::vector<Vec3>* p_W, std::vector<Vec2>* uv0) const;
  /// Their number (triangulatedIn's size, without computing the positions).
  int countTriangulatedFromElsewhere(FrameId frame) const;
  /// World positions of all triangulated landmarks.
  std::vector<Vec3> positions(const Window& window) const;
  void clear() { landmarks_.clear(); }
  const std::map<std::int64_t, PointLandmark>& all() const { return landmarks_; }

  /// World position of a triangulated landmark (its host must be in the window).
  Vec3 worldPosition(const Window& window, const PointLandmark& lm) const;

  /// The cameras' extrinsics from now on (the estimator's online refinement of the rig); residuals built
  /// afterwards use them.
  void setExtrinsics(const Pose& T_B_C0, std::optional<Pose> T_B_C1) {
    T_B_C0_ = T_B_C0;
    T_B_C1_ = std::move(T_B_C1);
  }

 private:
  bool triangulateOne(const Window& window, PointLandmark& lm) const;
  /// Mean reprojection error in pixels over the landmark's window sightings (cam0 outside the host, and cam1).
  double meanErrorPx(const Window& window, const WindowCameras& cams, const PointLandmark& lm) const;
  /// Takes part in solves: triangulated and seen in at least solver.min_observations window frames.
  bool usable(const PointLandmark& lm) const {
    return lm.triangulated && lm.obs.size() >= static_cast<std::size_t>(std::max(2, options_.min_observations));
  }
  bool depthOk(double depth) const { return depth >= options_.min_depth_m && depth <= options_.max_depth_m; }

  SolverOptions options_;
  Pose T_B_C0_;
  std::optional<Pose> T_B_C1_;
  std::map<std::int64_t, PointLandmark> landmarks_;
  FactorPool<PointReprojectionFactor> reprojection_factors_;  // residuals()' factors, reused from call to call
  FactorPool<PointStereoFactor> stereo_factors_;
};

}  // namespace linnet
