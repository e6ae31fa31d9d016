// A visual residual's cost function kept with the values it was built from, and reused while they stay the same.
//
// The window builds every visual residual again for each solve and each marginalisation (thousands per frame), and a
// cost function is two heap allocations (the object, and Ceres' list of its block sizes); most of them are built from
// the same observation, extrinsics and weight as the frame before. The factors hold no state that depends on earlier
// evaluations (LineReprojectionFactor's cache of pose terms is keyed by the pose's values), so a reused one evaluates
// exactly as a new one would.
#pragma once

#include <array>
#include <cstddef>
#include <cstring>
#include <memory>

#include <ceres/cost_function.h>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

template <std::size_t N>
class CostCache {
 public:
  using Key = std::array<double, N>;

  /// The cost function built by make() for `key`: the kept one if it was built for the same key (bit for bit).
  template <class Make>
  std::shared_ptr<ceres::CostFunction> get(const Key& key, Make&& make) {
    if (!cost_ || std::memcmp(key.data(), key_.data(), sizeof(Key)) != 0) {
      cost_ = make();
      key_ = key;
    }
    return cost_;
  }

 private:
  std::shared_ptr<ceres::CostFunction> cost_;
  Key key_{};
};

/// Writes a pose's 7 values (quaternion x y z w, position) at out[0..6]; returns out + 7.
inline double* putPose(const Pose& T, double* out) {
  for (int i = 0; i < 4; ++i) *out++ = T.q.coeffs()[i];
  for (int i = 0; i < 3; ++i) *out++ = T.p[i];
  return out;
}

inline double* putVec2(const Vec2& v, double* out) {
  *out++ = v.x();
  *out++ = v.y();
  return out;
}

}  // namespace linnet
