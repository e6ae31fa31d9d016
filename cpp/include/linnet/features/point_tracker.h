// The point front-end (DESIGN B1): KLT tracking with a forward-backward check, border and two-view RANSAC rejection,
// corner replenishment with a minimum-distance mask, stereo matching by KLT with a right->left and an epipolar check,
// undistortion to normalised coordinates, velocities, stable ids and track lengths.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/features/point_detection.h"

namespace cv {
class CLAHE;
}

namespace linnet {

struct PointTrackerOptions {
  int max_points = 150;                  // tracked features per frame in cam0
  double min_distance_px = 30.0;         // minimum distance between features, pixels
  // KLT (pyramidal Lucas-Kanade: lucasKanade, the arithmetic of cv::calcOpticalFlowPyrLK)
  int klt_window_px = 15;                // window side, pixels
  int klt_pyramid_levels = 3;            // levels above the full-resolution image
  int klt_max_iterations = 30;           // per level
  double klt_epsilon = 0.01;             // termination: update below this, pixels
  double klt_min_eigen = 1e-4;           // KLT drops windows whose gradient matrix's smallest eigenvalue (per pixel,
                                         // intensities scaled to [0, 1]) is below this: flat patches
  double fb_threshold_px = 0.5;          // forward-backward round trip error above which a track is dropped, pixels
  int fb_pyramid_levels = 3;             // pyramid levels of the backward pass (1 is cheaper but lets ~50% more
                                         // false tracks through on noise images)
  double border_px = 3.0;                // tracks closer to the image border are dropped, pixels
  // Two-view outlier rejection on undistorted points
  std::string outlier_rejection = "auto";  // "auto" (rotation when a prediction was given, else fundamental) |
                                           // "rotation" (2-point; fundamental when no prediction was given) |
                                           // "fundamental" | "none"
  double ransac_threshold_px = 1.0;      // epipolar distance, pixels (divided by the focal length)
  double ransac_confidence = 0.99;       // RANSAC stopping confidence
  int ransac_max_iterations = 200;       // hypotheses at most
  bool use_rotation_prediction = true;   // seed KLT with the predicted rotation when setRotationPrediction() was called
  bool klt_flow_prediction = true;       // also add each track's last motion beyond that rotation (its translational
                                         // flow, pixels per second, times the frame interval) to the KLT's start
  int klt_predicted_levels = 1;          // pyramid levels above full resolution for the tracks started from their
                                         // own flow (the start is then about a pixel off, so the coarse levels only
                                         // cost time); the tracks they lose are tracked again with all
                                         // klt_pyramid_levels
  // Replenishment
  std::string detector = "fast";         // "fast" | "shi_tomasi"
  int fast_threshold = 20;               // FAST intensity threshold, 0..255 (lowered automatically down to 5)
  int min_new_points = 8;                // replenish only when at least this many tracks are missing (each detection
                                         // pass costs a FAST search over the free image; a few missing tracks are
                                         // replaced a frame or two later)
  double shi_tomasi_quality = 0.01;      // fraction of the strongest Shi-Tomasi response
  int grid_cols = 8;                     // detection buckets across the image
  int grid_rows = 6;                     // detection buckets down the image
  // Stereo (left -> right KLT, right -> left check, epipolar check with the known extrinsic; no rectification)
  bool stereo = true;                    // match in cam1 when a right image is given
  double stereo_fb_threshold_px = 1.0;   // right -> left round trip error, pixels
  double stereo_epipolar_threshold_px = 1.5;  // distance of the right point to its epipolar line, pixels of cam1
  double stereo_min_depth_m = 0.1;       // closer stereo points are rejected, metres
  double stereo_search_min_depth_m = 0.3;  // the epipolar search for new matches spans this depth to infinity, metres
  double stereo_search_min_zncc = 0.6;   // the search's best patch correlation must reach this
  int stereo_retry_interval = 3;         // a track whose stereo match failed is tried again after this many frames
                                         // (occluded / out-of-view points fail every frame: this bounds their cost)
  int stereo_refresh_interval = 1;      // a track matched in cam1 is matched again only every this many frames
                                         // (1: every frame); in between it has no cam1 observation. 2: one-core
                                         // CPU real-time factor on MH_01 hall hard 0.286 -> 0.269, but APE on the
                                         // hard replays mixed (V2_01 +11 %, MH_04 +3 %, MH_01 -7 %), so 1 stays
  int stereo_search_level = 1;           // pyramid level of the epipolar search (0 = full resolution)
  int stereo_prior_levels = 0;           // KLT levels above full resolution for tracks matched in cam1 last frame
                                         // (started there, moved by their left flow: a median 0.09 px off on MH_01
                                         // hall hard); -1: as the searched ones (stereo_search_level)
  double stereo_prior_agree_px = 0.5;    // such a track whose cam1 KLT ends within this of its prior skips the
                                         // right -> left round trip (its last match confirms it; 0: never), pixels
  bool stereo_gain_compensation = true;  // match the right image's mean and contrast to the left's before stereo KLT
  // Image preprocessing
  bool clahe = false;                    // contrast-limited adaptive histogram equalisation before all tracking (as
                                         // VINS-Mono does). Its tiles stay put while the content moves: temporal KLT
                                         // error on a known rotation 0.055 -> 0.14 px median, so it is off by default
  bool stereo_clahe = true;              // CLAHE on copies used only for stereo matching (EuRoC: stereo matches
                                         // ~51% -> ~61% of the tracks; ~2 ms per stereo frame)
  bool stereo_clahe_adaptive = true;     // pay for stereo CLAHE only while it is needed: it is dropped while the raw
                                         // images match at least stereo_clahe_min_ratio of the attempted tracks
                                         // (tried again every stereo_clahe_probe_frames frames while CLAHE is on; a
                                         // raw try that falls short is matched again with CLAHE)
  double stereo_clahe_min_ratio = 0.8;   // fraction of attempted stereo matches that makes CLAHE unnecessary
  int stereo_clahe_probe_frames = 30;    // while CLAHE is on, one frame in this many is matched without it
  double clahe_clip_limit = 3.0;         // CLAHE clip limit
  int clahe_tiles = 8;                   // CLAHE tiles per side

  template <class V>
  void visit(V& v) {
    v("max_points", max_points, "tracked features per frame in cam0", 1, 5000);
    v("min_distance_px", min_distance_px, "minimum distance between features, pixels", 1.0, 500.0);
    v("klt_window_px", klt_window_px, "KLT window side, pixels", 5, 101);
    v("klt_pyramid_levels", klt_pyramid_levels, "KLT pyramid levels above full resolution", 0, 8);
    v("klt_max_iterations", klt_max_iterations, "KLT iterations per level", 1, 1000);
    v("klt_epsilon", klt_epsilon, "KLT termination step, pixels", 1e-6, 10.0);
    v("klt_min_eigen", klt_min_eigen, "KLT minimum eigenvalue of the window's gradient matrix", 0.0, 1.0);
    v("fb_threshold_px", fb_threshold_px, "forward-backward round trip error, pixels", 0.01, 100.0);
    v("fb_pyramid_levels", fb_pyramid_levels, "pyramid levels of the backward KLT pass", 0, 8);
    v("border_px", border_px, "tracks closer to the border are dropped, pixels", 0.0, 200.0);
    v.choice("outlier_rejection", outlier_rejection, "two-view outlier rejection",
             {"auto", "rotation", "fundamental", "none"});
    v("ransac_threshold_px", ransac_threshold_px, "RANSAC epipolar distance, pixels", 0.01, 100.0);
    v("ransac_confidence", ransac_confidence, "RANSAC stopping confidence", 0.5, 0.999999);
    v("ransac_max_iterations", ransac_max_iterations, "RANSAC hypotheses at most", 1, 100000);
    v("use_rotation_prediction", use_rotation_prediction, "seed KLT with the IMU rotation prediction");
    v("klt_flow_prediction", klt_flow_prediction, "seed KLT with each track's last translational flow as well");
    v("klt_predicted_levels", klt_predicted_levels, "KLT pyramid levels for tracks started from their own flow", 0, 8);
    v.choice("detector", detector, "corner detector for replenishment", {"fast", "shi_tomasi"});
    v("fast_threshold", fast_threshold, "FAST intensity threshold", 1, 255);
    v("min_new_points", min_new_points, "replenish only when at least this many tracks are missing", 1, 5000);
    v("shi_tomasi_quality", shi_tomasi_quality, "fraction of the strongest Shi-Tomasi response", 1e-6, 1.0);
    v("grid_cols", grid_cols, "detection buckets across the image", 1, 100);
    v("grid_rows", grid_rows, "detection buckets down the image", 1, 100);
    v("stereo", stereo, "match points in cam1 when a right image is given");
    v("stereo_fb_threshold_px", stereo_fb_threshold_px, "right -> left round trip error, pixels", 0.01, 100.0);
    v("stereo_epipolar_threshold_px", stereo_epipolar_threshold_px, "distance to the epipolar line, pixels", 0.01,
      100.0);
    v("stereo_min_depth_m", stereo_min_depth_m, "closer stereo points are rejected, metres", 0.0, 100.0);
    v("stereo_search_min_depth_m", stereo_search_min_depth_m, "epipolar search from this depth to infinity, metres",
      0.05, 100.0);
    v("stereo_search_min_zncc", stereo_search_min_zncc, "minimum patch correlation of the epipolar search", -1.0, 1.0);
    v("stereo_refresh_interval", stereo_refresh_interval, "frames between stereo matches of a matched track", 1,
      1000);
    v("stereo_search_level", stereo_search_level, "pyramid level of the epipolar search", 0, 8);
    v("stereo_prior_levels", stereo_prior_levels, "stereo KLT levels for tracks matched last frame (-1: as the others)",
      -1, 8);
    v("stereo_prior_agree_px", stereo_prior_agree_px,
      "a track ending this close to its stereo prior skips the round trip, pixels (0: never)", 0.0, 100.0);
    v("stereo_retry_interval", stereo_retry_interval, "frames before a failed stereo match is tried again", 1, 1000);
    v("stereo_gain_compensation", stereo_gain_compensation, "match the right image's mean and contrast to the left's");
    v("clahe", clahe, "CLAHE before all tracking");
    v("stereo_clahe", stereo_clahe, "CLAHE on the copies used for stereo matching");
    v("stereo_clahe_adaptive", stereo_clahe_adaptive, "stereo CLAHE only while raw images match too few tracks");
    v("stereo_clahe_min_ratio", stereo_clahe_min_ratio, "matched fraction that makes stereo CLAHE unnecessary", 0.0,
      1.0);
    v("stereo_clahe_probe_frames", stereo_clahe_probe_frames, "while stereo CLAHE is on, frames between raw tries", 2,
      100000);
    v("clahe_clip_limit", clahe_clip_limit, "CLAHE clip limit", 0.1, 100.0);
    v("clahe_tiles", clahe_tiles, "CLAHE tiles per side", 1, 64);
  }
};

/// What happened in the last track() call (for logs, tests and benchmarks).
struct PointTrackerStats {
  int previous = 0;        // tracks entering the frame
  int klt_failed = 0;      // lost by KLT, the forward-backward check or the border
  int ransac_rejected = 0; // removed by the two-view RANSAC
  int crowded = 0;         // removed because a longer track lies within min_distance_px
  int detected = 0;        // new corners
  int stereo_attempted = 0;      // tracks tried in cam1 this frame (the others failed recently, see stereo_retry_interval)
  int stereo_matched = 0;
  int stereo_search_failed = 0;   // no epipolar-search candidate reached stereo_search_min_zncc
  int stereo_klt_failed = 0;      // KLT lost, right -> left check failed, or outside cam1
  int stereo_round_trip_skipped = 0;  // matched near their prior, no right -> left check (stereo_prior_agree_px)
  int stereo_epipolar_rejected = 0;
  int stereo_depth_rejected = 0;  // negative or below stereo_min_depth_m
  bool used_rotation_prediction = false;
  double klt_start_error_px = 0.0;  // median distance of the tracked points from where KLT started, pixels
  int klt_retried = 0;               // flow-predicted tracks lost with klt_predicted_levels, tracked again with all
  bool used_stereo_clahe = false;  // stereo matching ran on CLAHE copies this frame
  double ms = 0.0;         // wall time of track(), milliseconds
};

class PointTracker {
 public:
  /// cam1 == nullptr: monocular. T_C1_C0 maps cam0 coordinates to cam1 (ignored for mono). The cameras must outlive
  /// the tracker. Throws ConfigError on out-of-range options.
  PointTracker(const PointTrackerOptions& options, const CameraModel& cam0, const CameraModel* cam1,
               const Pose& T_C1_C0);
  ~PointTracker();
  PointTracker(const PointTracker&) = delete;
  PointTracker& operator=(const PointTracker&) = delete;

  /// Tracks into the next frame. left: 8-bit grayscale of cam0's size; right: same for cam1, or empty (mono, or a
  /// frame without its right image). Appends one observation per track to *points, sorted by id.
  /// Throws UsageError on a wrong image type or size, or a time stamp not after the previous one.
  void track(Timestamp t, const cv::Mat& left, const cv::Mat& right, std::vector<PointObservation>* points);

  /// Optional prediction for the next track() call: rotation of cam0 from the previous to the current frame
  /// (p_Ccur = R_Ccur_Cprev p_Cprev), e.g. from integrated gyroscope rates. Used once, then forgotten.
  void setRotationPrediction(const Mat3& R_Ccur_Cprev);

  /// Drops every track (ids keep counting up, never reused).
  void reset();

  const PointTrackerStats& lastStats() const { return stats_; }
  const PointTrackerOptions& options() const { return opt_; }
  /// The last track() call's left image's FAST corners from replenishment's first round (threshold < 0 when it ran
  /// none, or ran on a CLAHE copy); moved out, so a second call returns none.
  FastCorners takeFastCorners() { return std::exchange(fast_corners_, FastCorners{}); }
  std::size_t numTracks() const { return tracks_.size(); }

 private:
  struct Track {
    std::int64_t id;
    cv::Point2f px;       // distorted pixel in cam0
    Vec2 uv;              // normalised in cam0
    Vec2 velocity;        // normalised units per second
    cv::Point2f flow;     // last frame's motion beyond the rotation prediction, distorted pixels per second
    int length;
    bool has_right;
    cv::Point2f px1;      // distorted pixel in cam1 (valid if has_right)
    Vec2 uv1;
    bool right_prior;     // px1 holds last frame's match moved by this frame's flow (a stereo prior)
    std::int64_t stereo_retry_frame;  // after a failed stereo attempt: the frame index of the next attempt
    std::int64_t stereo_frame;        // frame index of its last stereo match attempt with a prior
    bool stereo_skipped;              // matched before, not re-matched this frame (stereo_refresh_interval)
  };

  void trackTemporal(double dt);
  // KLT of the tracks `which` from prev to their start positions in the current frame with `levels` pyramid levels,
  // then the backward check: writes their results into *cur and *ok.
  void kltForwardBackward(const std::vector<cv::Point2f>& prev, const std::vector<cv::Point2f>& start,
                          const std::vector<std::size_t>& which, int levels, std::vector<cv::Point2f>* cur,
                          std::vector<unsigned char>* ok) const;
  void rejectOutliers(const std::vector<Vec2>& uv_prev);
  void replenish(const cv::Mat& image);
  // Stereo matching of the current tracks; stereo_clahe: on CLAHE copies of both images (left: the raw left image).
  // prior_shortcut: tracks with a stereo prior take stereo_prior_levels and stereo_prior_agree_px (otherwise the
  // full check of the searched ones).
  void stereoPass(const cv::Mat& left, const cv::Mat& right, bool stereo_clahe, bool prior_shortcut);
  void matchStereo(const std::vector<cv::Mat>& pyr_left, bool prior_shortcut);

  PointTrackerOptions opt_;
  const CameraModel& cam0_;
  const CameraModel* cam1_;
  Pose T_C1_C0_;
  cv::Ptr<cv::CLAHE> clahe_;

  std::vector<Track> tracks_;     // sorted by id
  std::int64_t next_id_ = 0;
  std::int64_t frame_index_ = 0;  // track() calls so far
  Timestamp last_t_ = 0;
  bool has_last_ = false;
  std::vector<cv::Mat> pyr_prev_, pyr_cur_, pyr_right_, pyr_left_stereo_;
  std::optional<Mat3> R_pred_;
  PointTrackerStats stats_;
  FastCorners fast_corners_;        // see takeFastCorners()
  bool stereo_clahe_on_ = true;     // adaptive stereo CLAHE: current state (starts on)
  int frames_since_probe_ = 0;      // stereo frames with CLAHE on since the last raw try
};

}  // namespace linnet
