// Line landmarks of the sliding window (DESIGN B1; thesis ch. 3-4): observations per frame, a Plücker block in W
// (optimised through LineManifold, the orthonormal 4-DoF update), triangulation from the stereo pair of one frame or
// from two frames of the window (two back-projection planes), the endpoint-to-line residuals for cam0 and cam1,
// outlier and degeneracy rejection, and a map of finite segments that outlives the window.
//
// Same shape as PointLandmarks: observe / triangulate / residuals / removeFrame / rejectOutliers, keys from
// lineBlockKey(). A line's "host" for marginalisation is its oldest observing window frame: when that frame is
// marginalised, every residual of the line goes into the prior with the line block dropped (as the points hosted
// there), and the line lives on in the window with its remaining observations.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <vector>

#include "linnet/core/frame_observations.h"
#include "linnet/core/map_line.h"
#include "linnet/core/pose.h"
#include "linnet/estimator/estimator_options.h"
#include "linnet/estimator/factor_pool.h"
#include "linnet/estimator/factors/line_factor.h"
#include "linnet/estimator/line_map_refinement.h"
#include "linnet/estimator/residual_spec.h"
#include "linnet/estimator/window.h"
#include "linnet/geometry/plucker.h"

namespace linnet {

struct LineFrameObs {
  Vec2 s0 = Vec2::Zero(), e0 = Vec2::Zero();  // normalised endpoints, cam0
  bool has_right = false;
  Vec2 s1 = Vec2::Zero(), e1 = Vec2::Zero();  // normalised endpoints, cam1
};

struct LineLandmark {
  std::int64_t id = -1;
  std::map<FrameId, LineFrameObs> obs;  // window frames, oldest first
  std::array<double, 6> plucker{};      // [n_W, v_W] (a parameter block, LineManifold)
  bool triangulated = false;
  bool used = false;                    // took part in the last solve
  bool solved = false;                  // took part in at least one solve (kept in the map when it leaves)
  int observations = 0;                 // frames that observed it over its life (the window's and earlier ones)
  Timestamp t_last = 0;                 // time of the newest frame that observed it, ns
  bool has_first_plane = false;
  Eigen::Vector4d first_plane = Eigen::Vector4d::Zero();  // back-projection plane of its first cam0 observation, W
  double max_sin_angle = 0.0;           // widest plane angle seen so far (stereo or first vs later frame), sine
  bool has_extent = false;
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();  // finite segment: extreme back-projected endpoints on the line, W
  std::vector<LineSighting> left_window;    // observations of frames that left the window, at their final poses
                                            // (cam0 and cam1; kept when options.map_refine)

  Vec6 L() const { return Eigen::Map<const Vec6>(plucker.data()); }
  void setL(const Vec6& L) { Eigen::Map<Vec6>(plucker.data()) = L; }
};

/// Why lines were removed by rejectOutliers (for logs and tests).
struct LineRejectionStats {
  int reprojection = 0;  // mean endpoint distance above outlier_px
  int sightings = 0;     // single sightings above max_observation_px dropped (their lines kept)
  int depth = 0;         // an endpoint behind a camera / out of the depth range, or too long
  int end_on = 0;        // seen end-on (degenerate)
  int drifted = 0;       // newest observation off the line's extent
};

class LineLandmarks {
 public:
  LineLandmarks(const LineOptions& options, double focal_length, const Pose& T_B_C0, std::optional<Pose> T_B_C1);

  /// Records the frame's (time t) line observations (ids may be new or known).
  void observe(FrameId frame, Timestamp t, const std::vector<LineObservation>& lines);
  /// Triangulates the lines that are not yet: the candidate (stereo pair of a frame, or cam0 in two frames) with the
  /// widest angle between the back-projection planes, if above options.min_plane_angle_deg, and if every observation
  /// back-projects in the depth range. Returns the number of newly triangulated lines.
  int triangulate(const Window& window);
  /// Residuals of the usable lines (triangulated, seen in >= min_observations window frames); marks them used. If
  /// host_only >= 0, only the lines whose oldest window observation is that frame (marginalisation), without touching
  /// `used`. frame_weight (may be empty): cost weight per observing frame (point / line weighting).
  std::vector<ResidualSpec> residuals(const Window& window, FrameId host_only = -1,
                                      const std::map<FrameId, double>& frame_weight = {});
  /// Drops the frame's observations (the frame is still in `window`: with options.map_refine they are kept for the
  /// map at its pose); lines left without window observations move to the map (if they were good).
  void removeFrame(const Window& window, FrameId frame);
  /// Removes used lines that fail a check after a solve (reprojection, depth, end-on, drift). Updates the extents of
  /// the remaining lines with the newest frame's observation. Returns how many were removed.
  int rejectOutliers(const Window& window);
  /// Before a solve (options.reidentify): a line seen for the first time in the newest frame whose cam0 (and cam1)
  /// segment lies within options.reid_px of the projection of exactly one solved window line not seen in that frame,
  /// with the same gradient polarity and touching its extent, is that line found again: its sighting joins the
  /// line, and the front-end's new id is an alias of it from now on. With options.reid_map, map lines in front of the
  /// camera are candidates too (one found again comes back into the window with its sightings). A second candidate
  /// within reid_ambiguity x reid_px whose distances differ from the nearest one's by more than reid_px (a parallel
  /// edge, not the same line twice) makes the sighting ambiguous. Returns how many were joined.
  int reidentify(const Window& window);
  /// Before a solve: drops the newest frame's sightings of solved lines that lie farther than
  /// options.max_observation_px from the line's projection at the frame's current (predicted) pose; returns how many.
  int gateNewest(const Window& window);
  /// Moves every triangulated, used line to the map and empties the window's lines (a new window starts).
  void clear();

  /// Lines observed in `frame` that are triangulated.
  int countTriangulatedIn(FrameId frame) const;
  /// Lines that took part in the last solve.
  int countUsed() const;
  /// Lines observed in `frame` (triangulated or not).
  int countObservedIn(FrameId frame) const;
  /// The map: lines that left the window plus the window's triangulated lines with an extent. Given the window,
  /// its lines are refined as the lines that left it are (options.map_refine): on their sightings that left the
  /// window and those still in it, at the window's poses.
  std::vector<MapLine> mapLines(const Window* window = nullptr) const;
  /// With options.map.adjust (or reid_map): the sightings of mapLines(window)'s lines, by id (the window's lines: those
  /// that left the window, then the window's at its poses); empty otherwise.
  std::map<std::int64_t, std::vector<LineSighting>> mapSightings(const Window& window) const;
  /// The window's triangulated lines with an extent, at their current estimate (by increasing id).
  std::vector<MapLine> windowLines() const;
  const std::map<std::int64_t, LineLandmark>& all() const { return landmarks_; }
  const LineRejectionStats& lastRejections() const { return rejections_; }

  /// Triangulation of one line from its window observations (exposed for tests). False if no candidate passes.
  bool triangulateOne(const Window& window, LineLandmark& lm) const;
  /// The same with the window's camera poses given (triangulate() computes them once for all its lines).
  bool triangulateOne(const Window& window, const WindowCameras& cams, LineLandmark& lm) const;

  /// The cameras' extrinsics from now on (the estimator's online refinement of the rig); residuals built
  /// afterwards use them.
  void setExtrinsics(const Pose& T_B_C0, std::optional<Pose> T_B_C1) {
    T_B_C0_ = T_B_C0;
    T_B_C1_ = std::move(T_B_C1);
  }

 private:
  /// The part of sighting `o`, given its cam0 / cam1 errors (pixels; cam1's read only if o.has_right), farther than
  /// options.max_observation_px from the line's projection: cam0 (the whole sighting goes), only cam1, or none.
  enum class BadPart { kNone, kCam0, kCam1 };
  BadPart badPart(double cam0_px, double cam1_px, const LineFrameObs& o) const;

  /// Each of the line's observations' cam0 / cam1 endpoint distance in pixels into *errors, in order (cam0 NaN for a
  /// frame not in the window, cam1 0 without a match); returns their mean over cam0 and the matched cam1 sightings.
  double sightingErrorsPx(const WindowCameras& cams, const LineLandmark& lm,
                          std::vector<std::array<double, 2>>* errors) const;
  /// Back-projects an observed segment onto the line: the two 3D points, false if a ray misses the depth range.
  bool backProject(const Vec6& L, const Pose& T_W_C, const Vec2& s, const Vec2& e, Vec3* a, Vec3* b) const;
  /// Extends the line's extent by a back-projected segment (keeps the two extreme points along the line).
  void extend(LineLandmark& lm, const Vec3& a, const Vec3& b) const;
  bool usable(const LineLandmark& lm) const {
    return lm.triangulated && lm.obs.size() >= static_cast<std::size_t>(std::max(2, options_.min_observations));
  }
  /// Distance along the line L between a back-projected segment a-b (on L) and the extent ext_a-ext_b, 0 if they
  /// overlap.
  static double extentGap(const Vec6& L, const Vec3& ext_a, const Vec3& ext_b, const Vec3& a, const Vec3& b);
  /// The map line map_[index] back in the window as landmark (its sightings kept), removed from the map.
  LineLandmark& restore(std::size_t index);
  /// The landmark a front-end id stands for: itself, or the line it was re-identified as (while that is in the window).
  std::int64_t landmarkId(std::int64_t frontend_id);
  /// Into the map, refined on all its sightings first when options.map_refine.
  void archive(LineLandmark& lm);
  /// Appends frame f's sightings of a line (cam0, and cam1 if matched) at f's pose to `out`.
  void appendSightings(const WindowFrame& f, const LineFrameObs& o, std::vector<LineSighting>* out) const;
  /// lm as a map line, refined on `sightings` when options.map_refine (the window estimate otherwise, or if the
  /// refinement fails).
  MapLine mapLineOf(const LineLandmark& lm, const std::vector<LineSighting>& sightings) const;

  LineOptions options_;
  double focal_length_;
  Pose T_B_C0_;
  std::optional<Pose> T_B_C1_;
  std::map<std::int64_t, LineLandmark> landmarks_;
  // A map line as the map keeps it: coordinates and quality in single precision, 56 bytes instead of MapLine's 88 (on
  // a long flight the map holds tens of thousands of lines; float is 1 um at 10 m, far below a line's own error).
  struct StoredMapLine {
    std::int64_t id = -1;
    Timestamp t_last = 0;
    std::array<float, 3> a{}, b{};
    float angle_deg = 0.0f, sigma_m = 0.0f;
    std::int32_t observations = 0;
    static StoredMapLine of(const MapLine& m);
    MapLine line() const;
  };
  // Lines that left the window, sorted by id (a later track of the id replaces it). On a long flight the map holds
  // tens of thousands of lines: a deque grows in blocks (a vector's doubling kept its old buffers with the allocator
  // and up to half its capacity unused), and a tree node would add to each line.
  std::deque<StoredMapLine> map_;
  // With options.reid_map, the sightings of the map's lines, by id (for their re-identification and refinement when
  // they are seen again); empty otherwise.
  std::map<std::int64_t, std::vector<LineSighting>> map_sightings_;
  // Front-end ids re-identified as an older window line (reidentify): new id -> the line's id, while it is in the window.
  std::map<std::int64_t, std::int64_t> alias_;
  LineRejectionStats rejections_;
  FactorPool<LineReprojectionFactor> factors_;  // residuals()' factors, reused from call to call
};

}  // namespace linnet
