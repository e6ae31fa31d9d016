// A line of the 3D map, as the estimator produces it and the map writers store it (a plain value type).
#pragma once

#include <cstdint>

#include "linnet/core/types.h"

namespace linnet {

/// A finite 3D segment in W (metres) and how many frames observed the line.
struct MapLine {
  std::int64_t id = -1;
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
  int observations = 0;
};

}  // namespace linnet
