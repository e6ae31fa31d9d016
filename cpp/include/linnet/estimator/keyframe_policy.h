// IMU-aided keyframe selection (thesis ch. 4 "keyframe selection", DESIGN B1).
//
// The IMU-integrated translation P and rotation Q since the last keyframe separate three cases:
//   small P (static or pure rotation): keyframe only if the parallax is large AND the rotation small, so that frames
//     whose parallax comes from rotation alone (no depth information) stay out of the window;
//   large P (translation): keyframe if the parallax is large.
// In every case too few points tracked from the last keyframe, or too long since it, force a keyframe.
#pragma once

#include <utility>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/estimator/estimator_options.h"

namespace linnet {

struct KeyframeInputs {
  double translation_m = 0.0;   // |P|: IMU-integrated translation since the last keyframe, m
  double rotation_rad = 0.0;    // |Q|: IMU-integrated rotation angle since the last keyframe, rad
  double parallax_px = 0.0;     // rotation-compensated mean parallax of points seen in both frames, pixels
  int tracked = 0;              // points seen in both frames
  double dt_s = 0.0;            // time since the last keyframe, s
};

enum class KeyframeReason { kNone, kParallax, kTooFewTracked, kTimeGap };

/// Decides whether the newest frame becomes a keyframe.
KeyframeReason keyframeDecision(const KeyframeOptions& options, const KeyframeInputs& in);

/// Mean parallax in pixels between correspondences (uv in the keyframe's cam0, uv in the new frame's cam0) after
/// rotating the keyframe's rays by R_Cnew_Ckf, so that pure rotation gives (nearly) zero parallax.
double compensatedParallaxPx(const std::vector<std::pair<Vec2, Vec2>>& kf_to_new, const Mat3& R_Cnew_Ckf,
                             double focal_length);

}  // namespace linnet
