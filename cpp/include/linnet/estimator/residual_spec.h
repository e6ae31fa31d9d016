// A residual block described independently of where it goes: into the per-frame Ceres problem or into the
// marginaliser. Every landmark kind (points now, lines later) and the IMU emit these, so the problem builder and the
// marginalisation code handle all kinds the same way.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <stdexcept>
#include <vector>

#include <ceres/cost_function.h>

namespace linnet {

/// The few blocks of one residual, stored inline: a window builds thousands of residuals per frame, and two heap
/// vectors each cost about as much as evaluating them. Holds at most kMaxResidualBlocks (a reprojection residual with
/// both calibration wrappers has 5); more is a programming error (std::length_error).
inline constexpr std::size_t kMaxResidualBlocks = 8;
template <class T>
class BlockList {
 public:
  BlockList() = default;
  BlockList(std::initializer_list<T> values) { assign(values); }
  BlockList& operator=(std::initializer_list<T> values) {
    assign(values);
    return *this;
  }
  void push_back(T v) {
    if (size_ == kMaxResidualBlocks) throw std::length_error("BlockList: more than kMaxResidualBlocks blocks");
    items_[size_++] = v;
  }
  std::size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  T& operator[](std::size_t i) { return items_[i]; }
  const T& operator[](std::size_t i) const { return items_[i]; }
  T* data() { return items_.data(); }
  const T* data() const { return items_.data(); }
  T* begin() { return items_.data(); }
  T* end() { return items_.data() + size_; }
  const T* begin() const { return items_.data(); }
  const T* end() const { return items_.data() + size_; }
  std::vector<T> vector() const { return std::vector<T>(begin(), end()); }

 private:
  void assign(std::initializer_list<T> values) {
    size_ = 0;
    for (const T& v : values) push_back(v);
  }
  std::array<T, kMaxResidualBlocks> items_{};
  std::size_t size_ = 0;
};

struct ResidualSpec {
  std::shared_ptr<ceres::CostFunction> cost;
  bool robust = false;                 // wrap in the Huber loss of the visual residuals
  bool line = false;                   // a line residual (its own Huber threshold), else a point or IMU residual
  BlockList<double*> blocks;           // parameter blocks, in the cost function's order
  BlockList<std::int64_t> keys;        // the same blocks as marginalisation keys
  std::int8_t cam1 = kNoCam1;          // where cam1 enters (the online stereo correction): kNoCam1, kCam1Pair (the
                                       // same-frame left-right point residual, PointStereoFactor) or the index of
                                       // the pose block whose frame is observed through cam1
  static constexpr std::int8_t kNoCam1 = -1;
  static constexpr std::int8_t kCam1Pair = -2;
};

/// Marginalisation keys of landmark blocks. Frame blocks use frameBlockKey() (>= 0), landmarks negative keys.
inline std::int64_t pointBlockKey(std::int64_t landmark_id) { return -(2 * landmark_id + 1); }
inline std::int64_t lineBlockKey(std::int64_t landmark_id) { return -(2 * landmark_id + 2); }
/// Key of the online rig-extrinsics correction (factors/pose_wrappers.h): non-negative, so it is kept like the frame
/// blocks, and never a frame block's key (those are 4 id + 0 or 1).
inline constexpr std::int64_t kRigBlockKey = 2;
/// Key of the online camera-to-IMU time offset (1 value, seconds); likewise.
inline constexpr std::int64_t kTimeOffsetBlockKey = 3;
/// Key of the online stereo correction S of cam1 relative to cam0 (factors/pose_wrappers.h); likewise (4 id + 2 with
/// id 1: no frame block has it).
inline constexpr std::int64_t kStereoBlockKey = 6;

}  // namespace linnet
