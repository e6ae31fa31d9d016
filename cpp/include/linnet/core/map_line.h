// A line of the 3D map, as the estimator produces it and the map writers store it (a plain value type).
#pragma once

#include <cstdint>
#include <limits>

#include "linnet/core/types.h"

namespace linnet {

/// A finite 3D segment in W (metres) and how many frames observed the line.
struct MapLine {
  std::int64_t id = -1;
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
  int observations = 0;
  Timestamp t_last = 0;        // time of the last frame that observed it, ns (0: unknown)
  double angle_deg = 0.0;      // widest angle between two of its back-projection planes (triangulation quality), deg
  double sigma_m = std::numeric_limits<double>::infinity();  // predicted endpoint std across the line, m (inf: unknown)
};

}  // namespace linnet
