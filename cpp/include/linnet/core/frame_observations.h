// What the front-end delivers to the estimator for one (stereo or mono) frame.
// Plain value types only: the estimator never sees an image, the front-end never sees Ceres.
#pragma once

#include <cstdint>
#include <vector>

#include "linnet/core/types.h"

namespace linnet {

/// One tracked point. Normalised coordinates are undistorted, on the z = 1 plane of the camera.
struct PointObservation {
  std::int64_t id = -1;        // stable across frames while tracked
  Vec2 uv0 = Vec2::Zero();     // normalised coordinates in cam0 (left)
  Vec2 px0 = Vec2::Zero();     // distorted pixel coordinates in cam0
  Vec2 velocity0 = Vec2::Zero();  // d(uv0)/dt in normalised units per second (0 on the first observation)
  bool has_right = false;      // matched in cam1 this frame
  Vec2 uv1 = Vec2::Zero();     // normalised coordinates in cam1 (valid if has_right)
  Vec2 px1 = Vec2::Zero();     // pixel coordinates in cam1 (valid if has_right)
  int track_length = 1;        // number of consecutive frames this id has been seen in cam0, this one included
};

/// One tracked line segment (start s, end e). Endpoints are undistorted normalised coordinates.
struct LineObservation {
  std::int64_t id = -1;
  Vec2 s0 = Vec2::Zero(), e0 = Vec2::Zero();    // normalised endpoints in cam0
  Vec2 ps0 = Vec2::Zero(), pe0 = Vec2::Zero();  // pixel endpoints in cam0
  bool has_right = false;
  Vec2 s1 = Vec2::Zero(), e1 = Vec2::Zero();    // normalised endpoints in cam1 (valid if has_right)
  Vec2 ps1 = Vec2::Zero(), pe1 = Vec2::Zero();  // pixel endpoints in cam1
  int track_length = 1;
};

/// All observations of one frame, each vector sorted by id (determinism).
struct FrameObservations {
  Timestamp t = 0;                  // image time stamp, ns, on the IMU clock
  std::vector<PointObservation> points;
  std::vector<LineObservation> lines;
  bool stereo = true;               // false for monocular input
  double point_ms = 0.0;            // wall time of the point worker for this frame
  double line_ms = 0.0;             // wall time of the line worker for this frame
};

}  // namespace linnet
