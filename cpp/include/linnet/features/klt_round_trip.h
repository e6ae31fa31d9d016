// Pyramidal KLT with a forward-backward (round trip) check, shared by the temporal and the stereo point matching.
#pragma once

#include <functional>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/features/lucas_kanade.h"

namespace linnet {

struct KltRoundTripParams {
  LucasKanadeParams forward;      // the forward pass (window, levels, iterations, step, minimum eigenvalue)
  int back_levels = 3;            // backward pass: pyramid levels above full resolution (else as the forward pass)
  double threshold_px = 1.0;      // largest distance of the backward result from the start point, pixels
};

/// The parameters from a tracker's KLT options (window side, iterations and step per level, minimum eigenvalue), with
/// the levels of both passes and the round trip's threshold.
inline KltRoundTripParams kltRoundTripParams(int window_px, int max_iterations, double epsilon, double min_eigen,
                                             int levels, int back_levels, double threshold_px) {
  KltRoundTripParams p;
  p.forward.window = cv::Size(window_px, window_px);
  p.forward.max_level = levels;
  p.forward.max_iterations = max_iterations;
  p.forward.epsilon = epsilon;
  p.forward.min_eigen = min_eigen;
  p.back_levels = back_levels;
  p.threshold_px = threshold_px;
  return p;
}

/// What happens to a point the forward pass tracked: dropped, kept without the backward pass, or checked by it.
enum class RoundTrip { kDrop, kKeep, kCheck };

/// Tracks `from` (in pyr_a) into pyr_b from the starts in *to (cv::OPTFLOW_USE_INITIAL_FLOW); *to receives the
/// forward results. `decide` (called with a point's index and its forward result, only for points the forward pass
/// kept) chooses what follows; the points it sends to the check are tracked back from their results to `from`'s
/// positions and kept when they end within threshold_px. Returns one flag per point (1: kept). The pyramids come
/// from buildPyramid or cv::buildOpticalFlowPyramid (derivative images, if any, are not read); KLT treats every point
/// alone, so a point's result does not depend on the others.
std::vector<unsigned char> kltRoundTrip(const std::vector<cv::Mat>& pyr_a, const std::vector<cv::Mat>& pyr_b,
                                        const std::vector<cv::Point2f>& from, std::vector<cv::Point2f>* to,
                                        const KltRoundTripParams& params,
                                        const std::function<RoundTrip(std::size_t, const cv::Point2f&)>& decide);

}  // namespace linnet
