// The published line map: the map lines whose predicted endpoint accuracy is within a bound.
//
// Every line that leaves the window becomes a map line with a predicted endpoint standard deviation (MapLine::sigma_m,
// from all its sightings at the frames' final poses: line_map_refinement.h). Many map lines are poorly constrained: a
// short track whose only baseline is the stereo pair, a far edge, a line seen close to its epipolar direction. Their
// depth errors reach decimetres although they fit their sightings as well as the good lines do (docs/known_issues.md,
// stop 42), and the predicted sigma is what tells them apart. The published map (map.ply, map_lines.csv,
// System::map()) holds the lines within the bound, as keyframe SLAM culls its poorly observed map points (e.g.
// ORB-SLAM's local mapping); the estimator's own map keeps every line, and an infinite bound publishes them all.
#pragma once

#include <cstddef>
#include <limits>
#include <vector>

#include "linnet/core/map_line.h"

namespace linnet {

struct LineMapOptions {
  double max_sigma_m = 0.02;  // publish the lines whose predicted endpoint std (MapLine::sigma_m) is at most this, m;
                              // infinity publishes every line. Low-texture replays (V1_02 / V2_02 / V2_01 lowtex):
                              // within 0.05 m 61 / 56 / 68 % of the lines at infinity, 92 / 92 / 90 % at 0.02 m, which
                              // keeps 66 / 61 / 67 % of the true lines the whole map holds a good line of (README)

  bool adjust = false;        // at the end of a run (loop closure on), the pose graph is solved again with the map
                              // lines, their passes over one physical line joined (LoopCloser::adjustLines): the
                              // corrected trajectory and the map move with it. Eight replays (README): APE -32 to +5 %,
                              // mean -14 %; 0.5-1.6 s CPU at the end of a run. Off: it keeps every map line's
                              // sightings (V1_02 lowtex, 83 s: resident set 93 -> 123 MB), unbounded on long runs
  double adjust_join_px = 1.0;  // two map lines join if one line fits each one's sightings within this, pixels
  bool adjust_publish_joined = false; // the adjusted map holds one line per joined group; false: every map line, each
                                      // re-estimated on its own sightings at the adjusted poses

  template <class V>
  void visit(V& v) {
    v("max_sigma_m", max_sigma_m, "publish map lines whose predicted endpoint std is at most this, m (inf: all)",
      0.0, std::numeric_limits<double>::infinity());
    v("adjust", adjust, "solve the pose graph again with the map lines at the end of a run (loop closure on)");
    v("adjust_publish_joined", adjust_publish_joined, "the adjusted map: one line per joined group (else every line)");
    v("adjust_join_px", adjust_join_px, "map lines join if one line fits both's sightings within this, pixels", 0.1,
      100.0);
  }
};

/// What curateLineMap did.
struct LineMapCurationStats {
  std::size_t input = 0;      // lines given
  std::size_t uncertain = 0;  // left out: sigma above options.max_sigma_m or unknown, or not a finite segment
  std::size_t published = 0;  // lines returned
};

/// The published map of `lines`: those with finite, distinct endpoints and sigma_m <= options.max_sigma_m (an unknown,
/// infinite or NaN sigma only with an infinite bound), in their order. Throws std::invalid_argument on a negative or
/// NaN bound.
std::vector<MapLine> curateLineMap(const std::vector<MapLine>& lines, const LineMapOptions& options,
                                   LineMapCurationStats* stats = nullptr);

}  // namespace linnet
