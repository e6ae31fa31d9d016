// Pyramidal Lucas-Kanade point tracking (J.-Y. Bouguet, "Pyramidal implementation of the Lucas Kanade feature
// tracker", Intel 2001): the computation of cv::calcOpticalFlowPyrLK with an initial flow, done with wider vectors.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

namespace linnet {

/// One pyramidal pass. The meaning (and clamping) of each field is that of cv::calcOpticalFlowPyrLK's argument.
struct LucasKanadeParams {
  cv::Size window{15, 15};   // window, pixels (both sides > 2)
  int max_level = 3;         // pyramid levels above full resolution (at most those both pyramids hold)
  int max_iterations = 30;   // per level, clamped to [0, 100]
  double epsilon = 0.01;     // a level stops when its update is at most this long, pixels (clamped to [0, 10])
  double min_eigen = 1e-4;   // points whose window's gradient matrix has a smaller eigenvalue per pixel are lost
  bool simd = true;          // the AVX2 kernels where the CPU has them (false: the plain ones; the same results)
};

/// Tracks `from` (pyramid `prev`) into pyramid `next`, each point starting at its entry of *to (the initial flow);
/// *to receives the results and *status 1 for a tracked point, 0 for a lost one. Both pyramids come from
/// cv::buildOpticalFlowPyramid (8-bit grey, padded by a window at least as large as params.window); derivative images
/// in them are not read: the previous image's Scharr derivatives are computed for each window, cheaper than reading
/// them (four bytes a pixel, where the cache holds few).
///
/// The arithmetic is OpenCV 4.6's on x86-64 (fixed-point bilinear weights with 14 bits, the window's samples with 5
/// fractional bits, its float sums in the same order), so the results equal cv::calcOpticalFlowPyrLK's bit for bit
/// there; the integer work (derivatives, sampling, residuals, products) runs over whole window rows in AVX2 where the
/// CPU has it. Each point is tracked alone: its result does not depend on the other points.
void lucasKanade(const std::vector<cv::Mat>& prev, const std::vector<cv::Mat>& next,
                 const std::vector<cv::Point2f>& from, std::vector<cv::Point2f>* to,
                 std::vector<unsigned char>* status, const LucasKanadeParams& params);

}  // namespace linnet
