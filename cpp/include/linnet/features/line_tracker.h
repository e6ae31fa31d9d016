// The line front-end: per stereo (or mono) frame, detect -> merge -> describe -> match to the previous frame ->
// replenish -> match left to right, delivering LineObservation's with stable ids (DESIGN A2, B1 "Line features").
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/frame_observations.h"
#include "linnet/core/pose.h"
#include "linnet/features/line_detector.h"
#include "linnet/features/line_lbd.h"
#include "linnet/features/line_matching.h"
#include "linnet/features/line_merge.h"
#include "linnet/features/line_types.h"

namespace linnet {

struct LineTrackerOptions {
  LineDetectorOptions detection;  // detection.detector selects "edlines" (default) | "fld" | "lsd"
  LineMergeOptions merge;
  LbdOptions lbd;
  TemporalMatchOptions temporal;
  StereoMatchOptions stereo;
  int max_lines = 80;          // lines delivered per frame (tracked first, then new ones)
  int grid_cols = 4;           // replenishment grid (cells of the image) for spatial spread
  int grid_rows = 3;
  int max_new_per_cell = 4;    // new lines started per grid cell and frame (by midpoint)
  double min_new_length_px = 40.0;  // shortest segment that starts a new track, pixels
  int max_missed = 2;          // frames a lost track is kept for re-detection (same id), 0 = none
  bool confirm_new = true;     // deliver a new line only from its second frame (drops one-frame flicker)
  bool match_stereo = true;    // false: ignore the right image

  template <class V>
  void visit(V& v) {
    v.section("detection", detection);
    v.section("merge", merge);
    v.section("lbd", lbd);
    v.section("temporal", temporal);
    v.section("stereo", stereo);
    v("max_lines", max_lines, "lines per frame", 1, 10000);
    v("grid_cols", grid_cols, "replenishment grid columns", 1, 64);
    v("grid_rows", grid_rows, "replenishment grid rows", 1, 64);
    v("max_new_per_cell", max_new_per_cell, "new lines per grid cell and frame", 1, 10000);
    v("min_new_length_px", min_new_length_px, "shortest segment starting a track, pixels", 0.0, 10000.0);
    v("max_missed", max_missed, "frames a lost track may be re-detected", 0, 100);
    v("confirm_new", confirm_new, "deliver new lines from their second frame on");
    v("match_stereo", match_stereo, "match lines in the right image");
  }
};

/// Tracks line segments over a stream of frames. Not thread-safe: one instance per stream; deterministic.
class LineTracker {
 public:
  /// cam1 == nullptr: monocular. T_C1_C0 maps cam0 coordinates to cam1. The camera models must outlive the tracker.
  /// Throws ConfigError (with the key) for invalid options.
  LineTracker(const LineTrackerOptions& options, const CameraModel& cam0, const CameraModel* cam1,
              const Pose& T_C1_C0);

  /// 8-bit grey images (right empty for mono, or ignored when there is no cam1). Appends this frame's lines to
  /// `lines`, sorted by id. Throws UsageError for a wrong image type or size, or time going backwards.
  void track(Timestamp t, const cv::Mat& left, const cv::Mat& right, std::vector<LineObservation>* lines);

  /// Optional prediction for the next track() call: rotation of cam0 from the previous to the current frame
  /// (p_Ccur = R_Ccur_Cprev p_Cprev), e.g. from integrated gyroscope rates. The previous lines (and the lost ones
  /// awaiting re-detection) are moved by the infinite homography K R K^-1 (through the distortion model) before
  /// the geometric gates; translation is left to the gates and the flow RANSAC. Used once, then forgotten.
  void setRotationPrediction(const Mat3& R_Ccur_Cprev) { R_pred_ = R_Ccur_Cprev; }

  const LineFrameTimings& lastTimings() const { return timings_; }
  const LineTrackerOptions& options() const { return options_; }

  /// The current frame's segments (pixels) as delivered, parallel to the last output (for debugging views).
  struct Track {
    std::int64_t id = -1;
    LineSegment px;        // left pixel endpoints
    LbdDescriptor desc{};  // left descriptor
    int length = 1;        // frames in which this id was delivered (gaps of <= max_missed frames allowed)
    int missed = 0;        // frames since last seen (0 for delivered tracks)
    bool tentative = false;  // started this frame, not delivered until matched again (confirm_new)
    std::int64_t stereo_frame = -1;  // index of the frame of its last stereo match (-1: none yet)
    Vec3 stereo_s = Vec3::Zero();    // left endpoints triangulated with that match, metres, in cam0 of that frame
                                     // turned by the rotation predictions since (the guided stereo pass's prior)
    Vec3 stereo_e = Vec3::Zero();
    Vec2 flow = Vec2::Zero();  // last motion of its midpoint beyond the rotation prediction, pixels per second
    // px undistorted (cam0 normalised) when it was delivered, and the px it was computed from: the next frame's
    // rotation prediction starts from the same px and reuses it while uv_of equals px.
    LineSegment uv{}, uv_of{};
    bool has_uv = false;
  };
  const std::vector<Track>& tracks() const { return tracks_; }

 private:
  void checkImage(const cv::Mat& img, const CameraModel& cam, const char* which) const;
  // Detects (oriented, unrefined), merges; descriptors computed on the way are kept in descs / described.
  void detectAndMerge(const cv::Mat& img, std::vector<LineSegment>* segs, std::vector<LbdDescriptor>* descs,
                      std::vector<char>* described, LineFrameTimings* tm);
  void refine(const cv::Mat& img, LineSegment* seg) const;
  bool undistortSegment(const CameraModel& cam, const LineSegment& px, LineSegment* uv) const;
  // Moves a cam0 pixel segment by a pure rotation; false (segment untouched) when an endpoint cannot be mapped.
  // `uv`: px undistorted, if known.
  bool rotateSegment(const Mat3& R_Ccur_Cprev, LineSegment* px, const LineSegment* uv = nullptr) const;
  // Guided stereo: the right segment (cam1 pixels) predicted for a track with a stereo prior, through its current
  // left segment (normalised), clipped to cam1's image; false when degenerate, out of the depth range or too short.
  bool predictRight(const Track& track, const LineSegment& left_uv, LineSegment* px) const;
  // Predicted left lines (temporal.detect_interval): the previous frame's lines prev_segs (rotation-predicted), moved
  // by their flow over dt seconds and refined on `left`. Fills the frame's segments and descriptors and match_of_cur;
  // returns the number found.
  int predictLeft(const cv::Mat& left, const std::vector<const Track*>& prev, const std::vector<LineSegment>& prev_segs,
                  double dt, std::vector<int>* match_of_cur, LineFrameTimings* tm);
  // Turns a track's stereo prior by the rotation prediction into the current frame (translation is neglected).
  void rotatePrior(const std::optional<Mat3>& R_Ccur_Cprev, Track* track) const;
  // Matches left lines in the right image (out / left_uv / left_desc parallel, track_of_left into tracks_).
  void matchRight(const cv::Mat& right, const std::vector<LineSegment>& left_uv,
                  const std::vector<LbdDescriptor>& left_desc, const std::vector<int>& track_of_left,
                  std::vector<LineObservation>* out, LineFrameTimings* tm);

  LineTrackerOptions options_;
  const CameraModel& cam0_;
  const CameraModel* cam1_;
  Pose T_C1_C0_;
  LineDetector detector_;
  LineDetectorOptions guided_refine_;  // the detection's refinement with the guided search width
  LineDetectorOptions predicted_refine_;  // the same with the predicted left lines' search width
  std::vector<Track> tracks_;
  std::vector<Track> lost_;       // recently lost tracks (missed 1..max_missed frames)
  std::vector<Track> tentative_;  // started last frame, awaiting confirmation
  std::int64_t next_id_ = 0;
  Timestamp last_t_ = 0;
  bool has_last_ = false;
  std::int64_t frame_index_ = 0;  // track() calls so far
  int frames_since_detection_ = 0;  // stereo frames since the right image's last full detection
  int frames_since_left_detection_ = 0;  // frames since the left image's last full detection
  int detection_matches_ = 0;       // stereo matches of the last full detection (before the final tests)
  LineFrameTimings timings_;
  std::optional<Mat3> R_pred_;
  // Scratch buffers reused across frames.
  std::vector<LineSegment> segs_l_, segs_r_;
  std::vector<LbdDescriptor> desc_l_, desc_r_;
  std::vector<char> described_l_, described_r_;
};

}  // namespace linnet
