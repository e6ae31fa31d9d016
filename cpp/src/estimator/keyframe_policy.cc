#include "linnet/estimator/keyframe_policy.h"

#include <cmath>

namespace linnet {

KeyframeReason keyframeDecision(const KeyframeOptions& o, const KeyframeInputs& in) {
  if (in.tracked < o.min_tracked) return KeyframeReason::kTooFewTracked;
  if (in.dt_s >= o.max_gap_s) return KeyframeReason::kTimeGap;
  const bool parallax = in.parallax_px > o.min_parallax_px;
  if (in.translation_m < o.static_translation_m) {
    // Static or pure rotation: rotation-induced parallax carries no depth information.
    const bool small_rotation = in.rotation_rad < o.max_rotation_deg * M_PI / 180.0;
    return parallax && small_rotation ? KeyframeReason::kParallax : KeyframeReason::kNone;
  }
  return parallax ? KeyframeReason::kParallax : KeyframeReason::kNone;
}

double compensatedParallaxPx(const std::vector<std::pair<Vec2, Vec2>>& kf_to_new, const Mat3& R_Cnew_Ckf,
                             double focal_length) {
  if (kf_to_new.empty()) return 0.0;
  double sum = 0.0;
  int n = 0;
  for (const auto& [a, b] : kf_to_new) {
    const Vec3 ray = R_Cnew_Ckf * Vec3(a.x(), a.y(), 1.0);
    if (ray.z() <= 1e-6) continue;
    sum += (ray.head<2>() / ray.z() - b).norm();
    ++n;
  }
  return n == 0 ? 0.0 : focal_length * sum / n;
}

}  // namespace linnet
