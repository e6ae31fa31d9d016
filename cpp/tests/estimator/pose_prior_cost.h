// A weighted pose prior for estimator tests: r = w [p - p0, 2 vec(q0^-1 q)] on a [p, q xyzw] block (for
// ceres::AutoDiffCostFunction<PosePrior, 6, 7>).
#pragma once

#include <Eigen/Geometry>

#include "linnet/core/pose.h"

namespace linnet::testing {

struct PosePrior {
  PosePrior(const Pose& T0, double w) : T0_(T0), w_(w) {}
  template <class T>
  bool operator()(const T* x, T* r) const {
    const Eigen::Quaternion<T> q(x[6], x[3], x[4], x[5]);
    const Eigen::Quaternion<T> dq = T0_.q.conjugate().cast<T>() * q;
    for (int k = 0; k < 3; ++k) r[k] = T(w_) * (x[k] - T(T0_.p[k]));
    for (int k = 0; k < 3; ++k) r[3 + k] = T(2.0 * w_) * dq.vec()[k];
    return true;
  }
  Pose T0_;
  double w_;
};

}  // namespace linnet::testing
