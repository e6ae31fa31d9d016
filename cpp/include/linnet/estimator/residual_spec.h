// A residual block described independently of where it goes: into the per-frame Ceres problem or into the
// marginaliser. Every landmark kind (points now, lines later) and the IMU emit these, so the problem builder and the
// marginalisation code handle all kinds the same way.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <ceres/cost_function.h>

namespace linnet {

struct ResidualSpec {
  std::shared_ptr<ceres::CostFunction> cost;
  bool robust = false;                 // wrap in the Huber loss of the visual residuals
  bool line = false;                   // a line residual (its own Huber threshold), else a point or IMU residual
  std::vector<double*> blocks;         // parameter blocks, in the cost function's order
  std::vector<std::int64_t> keys;      // the same blocks as marginalisation keys
};

/// Marginalisation keys of landmark blocks. Frame blocks use frameBlockKey() (>= 0), landmarks negative keys.
inline std::int64_t pointBlockKey(std::int64_t landmark_id) { return -(2 * landmark_id + 1); }
inline std::int64_t lineBlockKey(std::int64_t landmark_id) { return -(2 * landmark_id + 2); }
/// Key of the online rig-extrinsics correction (factors/pose_wrappers.h): non-negative, so it is kept like the frame
/// blocks, and never a frame block's key (those are 4 id + 0 or 1).
inline constexpr std::int64_t kRigBlockKey = 2;
/// Key of the online camera-to-IMU time offset (1 value, seconds); likewise.
inline constexpr std::int64_t kTimeOffsetBlockKey = 3;

}  // namespace linnet
