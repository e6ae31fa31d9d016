// The pinhole projection's derivative, shared by the estimator's point factors and the loop closure's PnP.
#pragma once
#include <Eigen/Core>

#include "linnet/core/types.h"

namespace linnet {

/// d (x / z, y / z) / d p for a point p in the camera frame (z > 0), 2 x 3.
inline Eigen::Matrix<double, 2, 3> projectionJacobian(const Vec3& p) {
  const double iz = 1.0 / p.z();
  Eigen::Matrix<double, 2, 3> D;
  D << iz, 0.0, -p.x() * iz * iz, 0.0, iz, -p.y() * iz * iz;
  return D;
}

}  // namespace linnet
