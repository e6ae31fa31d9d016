// Stereo matching of points, left -> right, without rectification: a coarse search along the epipolar curve of each
// point (ZNCC of small patches on a pyramid level), KLT refinement, a right -> left KLT check, the distance to the
// epipolar line and a cheirality / minimum-depth check.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

struct StereoPointParams {
  int klt_window_px = 15;             // KLT window side (the pyramids must be built with at least this), pixels
  int klt_levels = 3;                 // levels of the given pyramids above full resolution
  int klt_max_iterations = 30;
  double klt_epsilon = 0.01;          // pixels
  double klt_min_eigen = 1e-4;        // KLT's smallest gradient eigenvalue per pixel (flat patches are lost)
  int search_level = 1;               // pyramid level of the epipolar search (0 = full resolution)
  int search_half_patch = 3;          // ZNCC patch half size at the search level, pixels
  double search_min_depth_m = 0.3;    // the search covers depths from here to infinity, metres
  double search_min_zncc = 0.6;       // best candidate's ZNCC must reach this
  double fb_threshold_px = 1.0;       // right -> left round trip error, pixels
  int prior_levels = -1;              // levels above full resolution for the points with a prior (-1: as the others;
                                      // never more than they get)
  double prior_agree_px = 0.0;        // a point with a prior whose forward KLT ends within this distance of the prior
                                      // skips the round trip (0: every point takes it), pixels
  double verify_min_zncc = 0.7;       // full-resolution ZNCC of the final match must reach this (-1: no check)
  int verify_half_patch = 4;          // its patch half size, pixels
  double epipolar_threshold_px = 1.5; // distance of the right point to its epipolar line, pixels of cam1
  double min_depth_m = 0.1;           // closer points are rejected, metres
  double border_px = 3.0;             // right points closer to the border are rejected, pixels
};

struct StereoPointResult {
  bool ok = false;
  cv::Point2f px1;                  // distorted pixel in cam1
  Vec2 uv1 = Vec2::Zero();          // normalised coordinates in cam1
  double inverse_depth = 0.0;       // along the cam0 ray (z = 1 scaling), 1/m
};

struct StereoPointStats {
  int searched = 0;         // points that needed the epipolar search (no prior)
  int search_failed = 0;    // no candidate reached search_min_zncc
  int klt_failed = 0;       // KLT lost, round trip failed, or outside cam1
  int round_trip_skipped = 0;  // points with a prior that ended within prior_agree_px of it (no round trip)
  int epipolar_rejected = 0;
  int depth_rejected = 0;
  int verify_rejected = 0;  // full-resolution ZNCC below verify_min_zncc
  int matched = 0;
};

/// ZNCC of the (2h+1)^2 patches of two 8-bit images around sub-pixel centres (bilinear samples placed as
/// cv::getRectSubPix places them, pixels beyond the border replicated); -1 when either patch is flat (standard
/// deviation below 1e-3 grey levels). h in [0, 16].
double subpixelZncc(const cv::Mat& img0, const cv::Point2f& c0, const cv::Mat& img1, const cv::Point2f& c1, int h);

/// Matches cam0 points into cam1. pyr0 / pyr1: pyramids of cam0 / cam1 from buildPyramid (or
/// cv::buildOpticalFlowPyramid, with or without derivatives). px0 / uv0: the points in cam0 (pixels / normalised).
/// prior (optional, same size, may hold NaN for "none"): an expected cam1 pixel per point (e.g. last frame's match
/// moved by the point's flow); points with a prior skip the search. Deterministic.
std::vector<StereoPointResult> matchStereoPoints(const std::vector<cv::Mat>& pyr0, const std::vector<cv::Mat>& pyr1,
                                                 const CameraModel& cam0, const CameraModel& cam1,
                                                 const Pose& T_C1_C0, const std::vector<cv::Point2f>& px0,
                                                 const std::vector<Vec2>& uv0,
                                                 const std::vector<cv::Point2f>* prior,
                                                 const StereoPointParams& params, StereoPointStats* stats);

}  // namespace linnet
