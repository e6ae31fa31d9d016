// Corner detection for the point front-end: FAST (or Shi-Tomasi) corners, strongest first, spread over a grid and kept
// at least a minimum distance from each other and from the corners already tracked.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

namespace linnet {

struct PointDetectorParams {
  std::string detector = "fast";   // "fast" | "shi_tomasi"
  int fast_threshold = 20;         // FAST intensity difference (0..255); halved (down to 5) when too few corners
  double shi_tomasi_quality = 0.01;  // fraction of the strongest min-eigenvalue response
  int grid_cols = 8;               // buckets across the image
  int grid_rows = 6;               // buckets down the image
  double min_distance_px = 30.0;   // between accepted corners (and to existing tracks), pixels
  int border_px = 8;               // corners closer to the image border are ignored, pixels
};

/// The FAST corners (9-16, with non-maximum suppression) of a whole image at one threshold, as cv::FAST returns them:
/// what replenishment found in its first round, handed on so that a later user of the same image and threshold (the
/// loop closer's place description) need not search again. threshold < 0: none.
struct FastCorners {
  int threshold = -1;
  std::vector<cv::KeyPoint> keypoints;
};

/// Occupancy mask for detection: 255 where a new corner may go, 0 inside a disc of radius min_distance_px around each
/// existing point and in the border. `points` are visited in the given order; when `keep` is non-null, a point whose
/// centre is already covered by an earlier point's disc gets keep[i] = 0 (crowded), otherwise 1 and its disc is drawn.
cv::Mat detectionMask(const cv::Size& size, const std::vector<cv::Point2f>& points, double min_distance_px,
                      int border_px, std::vector<unsigned char>* keep);

/// Up to max_new corners of an 8-bit image where mask != 0 (mask is updated with a disc around each accepted corner).
/// Order of acceptance: by response, strongest first (ties by row, then column: deterministic), at most
/// ceil(2 max_new / cells) per grid cell in a first pass, then without the per-cell cap. FAST then repeats at half
/// the threshold (down to 5) while the quota is not filled. first_round (FAST only, may be null) receives the first
/// round's corners of the whole image, before the mask.
std::vector<cv::Point2f> detectCorners(const cv::Mat& image, cv::Mat* mask, int max_new,
                                       const PointDetectorParams& params, FastCorners* first_round = nullptr);

}  // namespace linnet
