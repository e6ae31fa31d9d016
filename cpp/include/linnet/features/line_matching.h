// Line matching: temporal (previous frame -> current frame, descriptor + geometric gating + flow consistency) and
// stereo (left -> right, descriptor + epipolar overlap of both endpoints with the calibrated extrinsics).
#pragma once

#include <functional>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/features/line_types.h"

namespace linnet {

struct TemporalMatchOptions {
  int max_hamming = 70;           // bits of 256
  double ratio = 0.85;            // best / second-best Hamming distance must be below this
  double max_angle_deg = 15.0;    // direction change between frames (same polarity), degrees
  double max_shift_px = 80.0;     // midpoint motion, pixels
  double min_overlap = 0.2;       // along-line overlap / shorter length after projection onto the previous line
  bool reject_outliers = true;    // RANSAC of a 4-DoF similarity flow on the normal displacements
  double outlier_px = 12.0;       // residual normal displacement to call a match an outlier, pixels
  int ransac_iterations = 100;
  int ransac_seed = 7;            // fixed seed: determinism
  int guided_max_hamming = 120;   // guided pass after the flow fit: descriptor bound, bits (0 = no guided pass)
  double guided_px = 3.0;         // guided pass: normal displacement off the fitted flow, pixels
  // The left image's full detection runs every detect_interval frames. In between, each line of the previous frame
  // (delivered, lost or tentative) is predicted into this frame (the rotation prediction, then its last motion across
  // the line beyond that rotation) and refined on the left image's edge; it is kept when enough of the refinement's
  // samples find the edge and its descriptor is close to the track's. No new lines start on such a frame. A frame
  // where fewer than predicted_min_fraction of the last frame's delivered lines are found is detected instead.
  int detect_interval = 1;               // 1: detection every frame, no predicted frames
  int predicted_search_px = 3;           // refinement search across the predicted segment, +- pixels
  double predicted_min_support = 0.6;    // fraction of the refinement's samples that must find the edge
  int predicted_max_hamming = 70;        // descriptor distance to the track's, bits (256 = no check)
  double predicted_min_fraction = 0.7;   // found / delivered last frame below this: the frame is detected instead
  int predicted_flow_neighbours = 6;     // a line new last frame moves by the flow fitted to this many nearest lines
                                         // (0: by the rotation only)

  template <class V>
  void visit(V& v) {
    v("max_hamming", max_hamming, "descriptor distance, bits", 0, 256);
    v("ratio", ratio, "best / second-best distance", 0.1, 1.0);
    v("max_angle_deg", max_angle_deg, "direction change, degrees", 0.0, 90.0);
    v("max_shift_px", max_shift_px, "midpoint motion, pixels", 1.0, 2000.0);
    v("min_overlap", min_overlap, "along-line overlap ratio", 0.0, 1.0);
    v("reject_outliers", reject_outliers, "similarity-flow RANSAC on normal displacements");
    v("outlier_px", outlier_px, "outlier threshold, pixels", 0.5, 500.0);
    v("ransac_iterations", ransac_iterations, "RANSAC iterations", 1, 100000);
    v("ransac_seed", ransac_seed, "RANSAC random seed", 0, 1 << 30);
    v("guided_max_hamming", guided_max_hamming, "guided pass descriptor bound, bits (0 = off)", 0, 256);
    v("guided_px", guided_px, "guided pass normal displacement off the flow, pixels", 0.1, 100.0);
    v("detect_interval", detect_interval, "full left-image detection every n-th frame, predicted lines between", 1,
      1000);
    v("predicted_search_px", predicted_search_px, "predicted lines' refinement search, +- pixels", 1, 10);
    v("predicted_min_support", predicted_min_support, "predicted lines: fraction of samples on the edge", 0.0, 1.0);
    v("predicted_max_hamming", predicted_max_hamming, "predicted lines: descriptor distance, bits", 0, 256);
    v("predicted_min_fraction", predicted_min_fraction, "predicted frame: lines found / delivered last frame", 0.0,
      1.0);
    v("predicted_flow_neighbours", predicted_flow_neighbours,
      "predicted lines new last frame: nearest lines whose flow they take (0 = rotation only)", 0, 100);
  }
};

struct StereoMatchOptions {
  int max_hamming = 70;                 // bits of 256
  double ratio = 0.85;                  // best / second-best Hamming distance
  double max_angle_deg = 15.0;          // direction difference left vs right (normalised coordinates), degrees
  double min_epipolar_angle_deg = 4.0;  // lines closer to parallel with the epipolar lines are not matched, degrees
  double min_overlap = 0.5;             // overlap of the left endpoints' epipolar span with the right segment
  double min_depth_m = 0.2;             // triangulated endpoint depth range in cam0, metres
  double max_depth_m = 60.0;
  // The right image's full detection runs every detect_interval frames. In between, the guided pass: a line matched
  // in cam1 within the last guided_max_age frames is predicted into this frame's right image from its triangulated
  // endpoints (turned by the rotation predictions; translation is neglected, which shifts the prediction by a
  // fraction of the disparity) through its current left segment, refined on the right image's edge and checked as a
  // detected match is. Lines without such a match have no cam1 observation on that frame. A frame where too few
  // lines have such a prior is detected instead (and restarts the count).
  int detect_interval = 2;              // 1: detection every frame, no guided pass
  int guided_search_px = 3;             // refinement search across the predicted right segment, +- pixels
  double guided_min_support = 0.6;      // fraction of the refinement's samples that must find the edge
  int guided_max_hamming = 70;          // descriptor distance to the left segment, bits (256 = no check)
  int guided_max_age = 3;               // frames since the line's last stereo match within which it is guided
  double guided_min_prior_fraction = 0.5;  // a frame is detected when fewer of its lines have a guided prior than
                                           // this fraction of the last detection's matches (or none has one)
  bool stagger_with_left = true;  // with predicted left lines (temporal.detect_interval > 1): detect the right image
                                  // on the frames whose left lines are predicted, guided on the others
  template <class V>
  void visit(V& v) {
    v("max_hamming", max_hamming, "descriptor distance, bits", 0, 256);
    v("ratio", ratio, "best / second-best distance", 0.1, 1.0);
    v("max_angle_deg", max_angle_deg, "direction difference, degrees", 0.0, 90.0);
    v("min_epipolar_angle_deg", min_epipolar_angle_deg, "minimum angle to the epipolar lines, degrees", 0.0, 45.0);
    v("min_overlap", min_overlap, "epipolar overlap ratio", 0.0, 1.0);
    v("min_depth_m", min_depth_m, "minimum depth, metres", 0.0, 1000.0);
    v("max_depth_m", max_depth_m, "maximum depth, metres", 0.01, 1e6);
    v("detect_interval", detect_interval, "full right-image detection every n-th frame, guided pass between", 1,
      1000);
    v("guided_search_px", guided_search_px, "guided refinement search, +- pixels", 1, 10);
    v("guided_min_support", guided_min_support, "guided refinement: fraction of samples on the edge", 0.0, 1.0);
    v("guided_max_hamming", guided_max_hamming, "guided match: descriptor distance, bits (256 = no check)", 0, 256);
    v("guided_max_age", guided_max_age, "guided pass: frames since the line's last stereo match", 1, 100);
    v("guided_min_prior_fraction", guided_min_prior_fraction,
      "lines with a guided prior / last detection's matches below which a frame is detected", 0.0, 1.0);
    v("stagger_with_left", stagger_with_left,
      "with predicted left lines: right detection on the predicted frames, guided on the detected ones");
  }
};

/// A candidate pair (i in set A, j in set B) with its descriptor distance.
struct LineMatchCandidate {
  int i = 0, j = 0, distance = 0;
};

/// Mutual-best selection with a ratio test on A's side: (i, j) is kept when j is i's best and i is j's best, the
/// distance is <= max_distance and below ratio * i's second-best distance. Ties go to the lower index (determinism).
/// Fills match_of_a (size n_a, -1 = none) and returns the number of matches.
int selectMutualBest(int n_a, int n_b, const std::vector<LineMatchCandidate>& candidates, int max_distance,
                     double ratio, std::vector<int>* match_of_a);

/// Previous -> current frame in pixels. match_of_cur[k] = index into prev, or -1. centre: the image centre (pixels),
/// origin of the similarity flow. Returns the number of matches after outlier rejection.
int matchTemporal(const TemporalMatchOptions& options, const std::vector<LineSegment>& prev,
                  const std::vector<LbdDescriptor>& prev_desc, const std::vector<LineSegment>& cur,
                  const std::vector<LbdDescriptor>& cur_desc, const Vec2& centre, std::vector<int>* match_of_cur);

/// As above, with the current descriptors computed on demand (only segments that pass the geometric gates of some
/// previous line are described): cur_desc(i) returns the descriptor of cur[i].
int matchTemporal(const TemporalMatchOptions& options, const std::vector<LineSegment>& prev,
                  const std::vector<LbdDescriptor>& prev_desc, const std::vector<LineSegment>& cur,
                  const std::function<const LbdDescriptor&(int)>& cur_desc, const Vec2& centre,
                  std::vector<int>* match_of_cur);

/// A flow (pixels per second) for a line that has none yet (new last frame), from the measured flows of the `count`
/// lines with the nearest midpoints (donor_segs / donor_flows parallel). A donor tells only its flow across itself
/// (its endpoints along the line are noise), so this is the least-squares fit of n_j . f = n_j . flow_j; a small ridge
/// keeps a direction no donor constrains (all parallel) at zero. Zero without donors or for count <= 0.
Vec2 neighbourFlow(const LineSegment& seg, const std::vector<LineSegment>& donor_segs,
                   const std::vector<Vec2>& donor_flows, int count);

/// Epipolar test of a left / right pair in normalised coordinates. On success, *overlap is the overlap ratio,
/// q_s, q_e (optional) the points of the right line corresponding to the left endpoints and depth (optional) the
/// depths in cam0 of the left endpoints triangulated with them, metres.
bool stereoGeometryOk(const StereoMatchOptions& options, const Mat3& E, const Pose& T_C1_C0, const LineSegment& left,
                      const LineSegment& right, double* overlap, Vec2* q_s = nullptr, Vec2* q_e = nullptr,
                      Vec2* depth = nullptr);

/// Geometric stage of matchStereo: every (left i, right j) pair whose directions agree and that passes
/// stereoGeometryOk; `distance` is left 0 for the caller to fill.
void stereoCandidates(const StereoMatchOptions& options, const Pose& T_C1_C0, const std::vector<LineSegment>& left,
                      const std::vector<LineSegment>& right, std::vector<LineMatchCandidate>* candidates);

/// Left -> right in normalised (undistorted) coordinates. T_C1_C0 maps cam0 coordinates to cam1.
/// match_of_left[k] = index into right, or -1. Returns the number of matches.
int matchStereo(const StereoMatchOptions& options, const Pose& T_C1_C0, const std::vector<LineSegment>& left,
                const std::vector<LbdDescriptor>& left_desc, const std::vector<LineSegment>& right,
                const std::vector<LbdDescriptor>& right_desc, std::vector<int>* match_of_left);

}  // namespace linnet
