// Pyramidal KLT with a forward-backward check (see klt_round_trip.h).
#include "linnet/features/klt_round_trip.h"

namespace linnet {

std::vector<unsigned char> kltRoundTrip(const std::vector<cv::Mat>& pyr_a, const std::vector<cv::Mat>& pyr_b,
                                        const std::vector<cv::Point2f>& from, std::vector<cv::Point2f>* to,
                                        const KltRoundTripParams& p,
                                        const std::function<RoundTrip(std::size_t, const cv::Point2f&)>& decide) {
  std::vector<unsigned char> ok(from.size(), 0);
  if (from.empty()) return ok;
  std::vector<unsigned char> st_f, st_b;
  lucasKanade(pyr_a, pyr_b, from, to, &st_f, p.forward);
  // The backward pass starts at the original positions, only for the points sent to it.
  std::vector<cv::Point2f> fwd, back;
  std::vector<std::size_t> fwd_idx;
  for (std::size_t k = 0; k < from.size(); ++k) {
    if (!st_f[k]) continue;
    const RoundTrip next = decide(k, (*to)[k]);
    if (next == RoundTrip::kKeep) ok[k] = 1;
    if (next != RoundTrip::kCheck) continue;
    fwd_idx.push_back(k);
    fwd.push_back((*to)[k]);
    back.push_back(from[k]);
  }
  if (fwd.empty()) return ok;
  LucasKanadeParams backward = p.forward;
  backward.max_level = p.back_levels;
  lucasKanade(pyr_b, pyr_a, fwd, &back, &st_b, backward);
  const double t2 = p.threshold_px * p.threshold_px;
  for (std::size_t j = 0; j < fwd_idx.size(); ++j) {
    const cv::Point2f d = back[j] - from[fwd_idx[j]];
    ok[fwd_idx[j]] = st_b[j] && d.dot(d) <= t2;
  }
  return ok;
}

}  // namespace linnet
