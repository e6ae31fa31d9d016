// Merging of broken segments (see line_merge.h).
#include "linnet/features/line_merge.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>

#include "linnet/core/error.h"

namespace linnet {

int mergeSegments(const LineMergeOptions& options, const SegmentDescriber& describe,
                  std::vector<LineSegment>* segments, std::vector<LbdDescriptor>* descriptors,
                  std::vector<char>* described) {
  const int n = static_cast<int>(segments->size());
  if (descriptors->empty() && described->empty()) {
    descriptors->assign(n, LbdDescriptor{0, 0, 0, 0});
    described->assign(n, 0);
  }
  if (static_cast<int>(descriptors->size()) != n || static_cast<int>(described->size()) != n)
    throw UsageError("mergeSegments: segments, descriptors and flags differ in size");
  auto desc = [&](int k) -> const LbdDescriptor& {
    if (!(*described)[k]) {
      (*descriptors)[k] = describe((*segments)[k]);
      (*described)[k] = 1;
    }
    return (*descriptors)[k];
  };
  int merges = 0;
  if (options.enabled && n >= 2) {
    const double cos_max = std::cos(options.max_angle_deg * std::numbers::pi / 180.0);
    std::vector<char> alive(n, 1);
    // Longest first, so that a long segment absorbs its pieces.
    std::vector<int> order(n);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(),
                     [&](int a, int b) { return (*segments)[a].length() > (*segments)[b].length(); });
    // Directions computed once: a segment changes only while it is the absorbing one (a below), and by then every
    // segment it is compared with comes later in the order and is still as detected.
    std::vector<Vec2> dirs(static_cast<std::size_t>(n));
    for (int k = 0; k < n; ++k) dirs[static_cast<std::size_t>(k)] = (*segments)[k].direction();
    for (int oi = 0; oi < n; ++oi) {
      const int i = order[oi];
      if (!alive[i]) continue;
      bool grew = true;
      while (grew) {
        grew = false;
        LineSegment& a = (*segments)[i];
        const Vec2 d = a.direction();
        const Vec2 nrm(-d.y(), d.x());
        const double la = a.length();
        for (int oj = oi + 1; oj < n; ++oj) {
          const int j = order[oj];
          if (!alive[j]) continue;
          const LineSegment& b = (*segments)[j];
          if (dirs[static_cast<std::size_t>(j)].dot(d) < cos_max) continue;
          if (std::abs((b.s - a.s).dot(nrm)) > options.max_perpendicular_px ||
              std::abs((b.e - a.s).dot(nrm)) > options.max_perpendicular_px)
            continue;
          const double ts = (b.s - a.s).dot(d), te = (b.e - a.s).dot(d);
          const double lo = std::min(ts, te), hi = std::max(ts, te);
          const double gap = std::max(0.0, std::max(lo - la, -hi));
          if (gap > options.max_gap_px) continue;
          if (hammingDistance(desc(i), desc(j)) > options.max_hamming) continue;
          // Keep the two farthest endpoints along a's direction.
          const Vec2 cand[4] = {a.s, a.e, b.s, b.e};
          const double t[4] = {0.0, la, ts, te};
          int imin = 0, imax = 1;
          for (int k = 0; k < 4; ++k) {
            if (t[k] < t[imin]) imin = k;
            if (t[k] > t[imax]) imax = k;
          }
          a.s = cand[imin];
          a.e = cand[imax];
          alive[j] = 0;
          (*described)[i] = 0;  // recomputed on the next comparison (or by the caller)
          ++merges;
          grew = true;
          break;
        }
      }
    }
    if (merges > 0) {
      std::vector<int> keep;
      for (int k = 0; k < n; ++k)
        if (alive[k]) keep.push_back(k);
      std::stable_sort(keep.begin(), keep.end(),
                       [&](int x, int y) { return (*segments)[x].length() > (*segments)[y].length(); });
      std::vector<LineSegment> segs;
      std::vector<LbdDescriptor> descs;
      std::vector<char> flags;
      for (int k : keep) {
        segs.push_back((*segments)[k]);
        descs.push_back((*descriptors)[k]);
        flags.push_back((*described)[k]);
      }
      segments->swap(segs);
      descriptors->swap(descs);
      described->swap(flags);
    }
  }
  return merges;
}

}  // namespace linnet
