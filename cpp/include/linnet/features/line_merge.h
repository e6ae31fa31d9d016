// Merging of broken segments of one physical line (thesis 3.1.2, DESIGN B1).
#pragma once

#include <functional>
#include <vector>

#include "linnet/features/line_types.h"

namespace linnet {

struct LineMergeOptions {
  bool enabled = true;
  double max_angle_deg = 3.0;         // direction difference (same gradient polarity required), degrees
  double max_perpendicular_px = 2.0;  // distance of the shorter segment's endpoints to the longer one's line, pixels
  double max_gap_px = 25.0;           // gap between the nearest endpoints along the line, pixels
  int max_hamming = 100;              // LBD agreement: Hamming distance, bits of 256

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "merge broken segments");
    v("max_angle_deg", max_angle_deg, "direction difference, degrees", 0.0, 45.0);
    v("max_perpendicular_px", max_perpendicular_px, "perpendicular distance, pixels", 0.0, 50.0);
    v("max_gap_px", max_gap_px, "endpoint gap along the line, pixels", 0.0, 500.0);
    v("max_hamming", max_hamming, "descriptor Hamming distance, bits", 0, 256);
  }
};

/// Computes the descriptor of a segment on demand (merging describes only the segments of candidate pairs).
using SegmentDescriber = std::function<LbdDescriptor(const LineSegment&)>;

/// Merges segments in place: a pair merges when their directions (same polarity) differ by less than max_angle_deg,
/// the shorter one's endpoints lie within max_perpendicular_px of the longer one's line, the gap between their nearest
/// endpoints along it is below max_gap_px (overlapping duplicates merge too) and their descriptors agree. The merged
/// segment keeps the two farthest endpoints, oriented as the longer one, and gets a recomputed descriptor before it
/// is compared again. `descriptors` / `described` run parallel to `segments` (empty = nothing described yet) and are
/// updated: merged-away entries are erased, the output holds every descriptor computed. The output is sorted by
/// decreasing length. Returns the number of merges.
int mergeSegments(const LineMergeOptions& options, const SegmentDescriber& describe,
                  std::vector<LineSegment>* segments, std::vector<LbdDescriptor>* descriptors,
                  std::vector<char>* described);

}  // namespace linnet
