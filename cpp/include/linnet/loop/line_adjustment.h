// The global adjustment of the line map (at the end of a run, after the last loop closure).
//
// Every map line is estimated from one pass of the camera: a physical line seen on several passes becomes several
// map lines, each placed by its pass's poses, and the passes' poses disagree by about the trajectory's error. With
// true poses, one line estimated from all the passes is twice as accurate as each pass's (docs/known_issues.md, stop
// 42); with the estimated poses it barely helps, so the poses must move with the lines. This adjustment joins the
// map lines of one physical line (near, parallel and explained by one line within a pixel bound, in the
// loop-corrected world) and solves the pose graph again with them: each joined line's sightings constrain the
// corrections of the keyframes that saw it (PoseGraph::optimise with GraphLine), as a global bundle adjustment of the
// lines over the keyframes' 4-DoF corrections. Every map line is then re-estimated on its sightings at the corrected
// poses.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

#include "linnet/core/map_line.h"
#include "linnet/estimator/line_map_refinement.h"

namespace linnet {

struct LineAdjustmentOptions {
  double focal_px = 460.0;       // pixels per normalised unit
  double pixel_sigma = 1.5;      // std of an endpoint distance, pixels
  double join_px = 2.0;          // two map lines join if one line fits each one's sightings within this mean, pixels
                                 // (the System passes estimator.lines.map.adjust_join_px, 1 px)
  double join_angle_deg = 2.0;   // join candidates: directions within this angle, deg
  double join_distance_m = 0.1;  // and both endpoints of one within this of the other's line, m
  double join_gap_m = 0.3;       // and their extents at most this far apart along it, m
  double min_depth_m = 0.1;      // depth range of the back-projected extents, m
  double max_depth_m = 30.0;
  double max_length_m = 20.0;    // longest segment, m
  bool publish_joined = false;   // a joined group is one map line; false: each map line re-estimated on its own
                                 // sightings at the adjusted poses
};

struct LineAdjustmentStats {
  std::size_t lines = 0;      // map lines given
  std::size_t joined = 0;     // of which joined to another
  std::size_t groups = 0;     // joined lines: the physical lines they make
  bool solved = false;        // the pose-graph solve with lines succeeded
  double cpu_s = 0.0;         // the adjustment's CPU time, s
};

}  // namespace linnet
