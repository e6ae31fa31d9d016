// Value types shared by the line front-end: segments, LBD descriptors, per-frame timings.
#pragma once

#include <array>
#include <bit>
#include <cstdint>

#include "linnet/core/types.h"

namespace linnet {

/// A detected line segment in (distorted) pixel coordinates of one image.
/// Orientation convention: walking from s to e, the brighter side is on the right in image coordinates
/// (x right, y down), i.e. the image gradient across the segment points along +n with n = (-d.y, d.x), d = (e - s)/|e - s|.
/// Detectors, refinement and merging keep this, so that s and e correspond across frames and cameras.
struct LineSegment {
  Vec2 s = Vec2::Zero();  // start point, pixels
  Vec2 e = Vec2::Zero();  // end point, pixels
  double length() const { return (e - s).norm(); }
  Vec2 direction() const { return (e - s).normalized(); }
  Vec2 normal() const {
    const Vec2 d = direction();
    return Vec2(-d.y(), d.x());
  }
  Vec2 midpoint() const { return 0.5 * (s + e); }
};

/// 256-bit binary LBD descriptor (Zhang & Koch, "An efficient and robust line segment matching approach based on
/// LBD descriptor and pairwise geometric consistency", JVCI 2013).
using LbdDescriptor = std::array<std::uint64_t, 4>;

/// Hamming distance between two descriptors, in bits (0..256).
inline int hammingDistance(const LbdDescriptor& a, const LbdDescriptor& b) {
  return std::popcount(a[0] ^ b[0]) + std::popcount(a[1] ^ b[1]) + std::popcount(a[2] ^ b[2]) +
         std::popcount(a[3] ^ b[3]);
}

/// Wall time of each stage of LineTracker::track for one frame, milliseconds. Stages sum over both images.
struct LineFrameTimings {
  double detect_ms = 0.0;    // detection + sub-pixel refinement, left + right
  double merge_ms = 0.0;     // merging of broken segments, left + right
  double describe_ms = 0.0;  // LBD descriptors (incl. recomputation after merging), left + right
  double temporal_ms = 0.0;  // matching to the previous frame, outlier rejection, id bookkeeping, replenishment
  double stereo_ms = 0.0;    // left -> right matching (incl. undistortion of endpoints)
  double left_ms = 0.0;      // everything the left image needs alone (detect, merge, describe, temporal)
  double total_ms = 0.0;     // whole call to track()
  double cpu_left_ms = 0.0;  // CPU time of this thread for the left-image part (robust to other processes' load)
  double cpu_total_ms = 0.0; // CPU time of this thread for the whole call
  int detected_left = 0;     // segments after length filter and merging
  int detected_right = 0;
  int tracked = 0;           // lines matched to the previous frame
  int new_lines = 0;         // new ids started this frame
  int stereo_matched = 0;    // output lines with a right observation
  int stereo_guided = 0;     // of those, matched by the guided pass (predicted from the previous frame's match)
  bool right_detected = false;  // the right image's full detection ran this frame
  bool left_detected = true;    // the left image's full detection ran this frame (else its lines were predicted)
  int left_predicted = 0;       // lines found by prediction and refinement on a frame without left detection
};

}  // namespace linnet
