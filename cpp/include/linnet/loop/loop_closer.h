// Loop closure for the stereo-inertial odometry (DESIGN A1 "loop"): a keyframe database, loop detection with
// geometric verification, and a 4-DoF pose graph that corrects the trajectory and the map.
//
// Detection: the odometry's drift is small (a fraction of a percent of the path), so a place seen before is
// searched among the old keyframes near the new keyframe's position as corrected so far, within a radius that grows
// with the path travelled since, and with a similar viewing direction. Each candidate (nearest first) is verified by
// ORB descriptor matching and PnP RANSAC against the old keyframe's stereo points (place_matcher.h). A verified loop
// adds an edge to the pose graph (pose_graph.h), which is then solved. The odometry itself is not changed: the loop
// closer keeps T_Wcorrected_Wodometry per keyframe, which maps odometry poses and map elements of that time into the
// corrected world (the drift correction of VINS-Mono, sec. VIII).
//
// The search does not relocalise a lost tracker (that needs place recognition without a position prior, e.g. a bag
// of binary words); it closes loops while the odometry runs.
#pragma once

#include <deque>
#include <map>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/loop/line_adjustment.h"
#include "linnet/loop/loop_options.h"
#include "linnet/loop/place_matcher.h"
#include "linnet/loop/place_store.h"
#include "linnet/loop/pose_graph.h"

namespace linnet {

struct LoopEvent {
  Timestamp t_new = 0, t_old = 0;  // keyframe times
  int inliers = 0;
  double correction_m = 0.0;       // position change of the new keyframe by the pose-graph solve, m
  double correction_yaw_deg = 0.0; // its yaw change, deg
  Pose T_old_new;                  // the loop's measured relative pose: new keyframe's body in the old one's
  double sigma_m = 0.0;            // the loop edge's position sigma in the pose graph, m
  double sigma_yaw_deg = 0.0;      // and its yaw sigma, deg
  PlaceMatchMethod method = PlaceMatchMethod::kDescriptors;  // how the loop was verified
};

/// The loop closer's database and graph sizes (what its memory and its solves grow with).
struct LoopStats {
  std::size_t keyframes = 0;    // keyframes inserted
  std::size_t graph_nodes = 0;  // of which kept as pose-graph nodes
  std::size_t described = 0;    // of which keep a place description
  std::size_t graph_solves = 0; // pose-graph solves (a loop the graph already agrees with needs none)
  double place_mb = 0.0;        // heap memory of the place descriptions (StoredPlace::bytes), MB
};

class LoopCloser {
 public:
  /// cam0 (kept by reference: it must outlive the loop closer), T_B_C0 and T_C1_C0 from the calibration.
  LoopCloser(const LoopOptions& options, const CameraModel& cam0, const Pose& T_B_C0, const Pose& T_C1_C0);

  /// A new keyframe at its (final) odometry pose, with its left image and tracked corners, inserted at once (its
  /// corners' depths from stereo). Returns true if it closed a loop.
  bool addKeyframe(Timestamp t, const Pose& T_W_B, const cv::Mat& left, const std::vector<PointObservation>& points);

  /// The way a running odometry feeds it: a new keyframe is described now (the image is at hand) but inserted only
  /// once it has left the odometry's window, at its final pose and with its corners at the window's final landmark
  /// positions (multi-view, better than one stereo pair), as VINS-Mono does with its window's old keyframes.
  /// Its tracked cam0 lines (`lines`) are described too when options.use_lines. `corners` (may be null): the left
  /// image's FAST corners if the front-end found them already (describePlace); `line_desc` (may be null): the lines'
  /// descriptors from the line tracker, parallel to `lines` (describePlaceLines).
  void queueKeyframe(Timestamp t, const Pose& T_W_B, const cv::Mat& left, const std::vector<PointObservation>& points,
                     const std::vector<LineObservation>& lines = {}, const FastCorners* corners = nullptr,
                     const std::vector<LbdDescriptor>* line_desc = nullptr);
  /// The odometry's window after a frame (oldest first), its triangulated point landmarks (sorted by id) and its line
  /// landmarks (sorted by id, endpoints in W): updates the queued keyframes still in it, and inserts those that have
  /// left it. Returns the loops closed.
  int updateWindow(const std::vector<std::pair<Timestamp, Pose>>& window,
                   const std::vector<std::pair<std::int64_t, Vec3>>& landmarks,
                   const std::vector<MapLine>& line_landmarks = {});
  /// The rig's extrinsics as the odometry now uses them (its online refinement, EstimatorOutput::T_B_R * T_B_C0);
  /// used for what follows: landmark depths and loop measurements.
  void setExtrinsics(const Pose& T_B_C0) { T_B_C0_ = T_B_C0; }
  /// Inserts every queued keyframe and solves the whole graph if loop edges were added since its last whole solve
  /// (solved in the newest nodes only, or not solved: consistent with the graph) (end of the stream).
  int flush();
  /// The global adjustment of the line map (line_adjustment.h), after flush(): `lines` in the odometry's world with
  /// their sightings by id (lines without sightings are only corrected). Solves the pose graph again with the joined
  /// lines (the corrections, hence correctionAt, change) and returns every line re-estimated at the corrected poses,
  /// in the corrected world; a joined line keeps its best-constrained member's id.
  std::vector<MapLine> adjustLines(const std::vector<MapLine>& lines,
                                   const std::map<std::int64_t, std::vector<LineSighting>>& sightings,
                                   const LineAdjustmentOptions& options, LineAdjustmentStats* stats = nullptr);
  bool hasQueued() const { return !queued_.empty(); }

  /// T_Wcorrected_Wodometry in force at time t: the correction of the last pose-graph node at or before t (identity
  /// before the first keyframe).
  Pose correctionAt(Timestamp t) const;
  /// The correction of the newest pose-graph node (a culled revisit after it would have had the same).
  Pose latestCorrection() const;
  /// A map line of the odometry's world in the corrected one: moved by the correction at its last sighting
  /// (correctionAt(t_last); the latest correction if t_last is unknown).
  MapLine correctedLine(MapLine line) const;

  const std::vector<LoopEvent>& loops() const { return loops_; }
  /// Keyframes inserted so far.
  std::size_t keyframes() const { return inserted_; }
  /// Keyframes that keep a place description (a revisit of a described place keeps none: options.place_reuse_m).
  std::size_t describedKeyframes() const;
  /// Keyframes, pose-graph nodes (a revisit without a loop is none: options.cull_revisits), descriptions, solves.
  LoopStats stats() const;

 private:
  struct Keyframe {
    Timestamp t = 0;
    StoredPlace place;
    double path_m = 0.0;  // odometry path length up to this keyframe (every keyframe's, culled or not)
  };
  struct Queued {
    Timestamp t = 0;
    Pose T_W_B;
    PlaceFeatures place;
    std::vector<Vec3> p_W;  // the window's landmark position of each tracked corner at T_W_B's estimate (NaN: none)
    std::vector<MapLine> lines_W;  // the window's line landmarks of its tracked lines at that estimate (sorted by id)
  };
  bool insert(Timestamp t, const Pose& T_W_B, PlaceFeatures place);
  /// Inserts the queued keyframes older than `limit`, with their corners at their last landmark positions; returns
  /// the loops closed.
  int insertQueuedBefore(Timestamp limit);
  bool tryLoop(std::size_t new_index, const PlaceFeatures& place);  // place: the new keyframe's description
  bool placeDescribedBefore(std::size_t k) const;
  PoseGraphOptions solveOptions() const;  // of a solve of the whole graph

  LoopOptions options_;
  const CameraModel& cam0_;
  Pose T_B_C0_, T_C1_C0_;
  std::vector<Keyframe> keyframes_;  // the pose graph's nodes, in time order (index = node index)
  std::deque<Queued> queued_;
  PoseGraph graph_;
  std::vector<LoopEvent> loops_;
  std::size_t inserted_ = 0;            // keyframes inserted
  std::size_t solves_ = 0;              // pose-graph solves
  bool whole_solve_pending_ = false;    // loop edges were added since the last whole solve (held nodes, or none)
  std::size_t last_loop_keyframe_ = 0;  // insertion count - 1 of the last keyframe that closed a loop
  bool any_loop_ = false;
  double path_m_ = 0.0;                 // odometry path length up to the newest keyframe, m
  Vec3 last_odometry_p_ = Vec3::Zero(); // the newest keyframe's odometry position
};

}  // namespace linnet
