// The sliding window: up to window_size keyframes plus the newest frame, oldest first.
//
// Each frame owns its Ceres parameter blocks (pose [p, q xyzw], speed-bias [v, b_a, b_g]; layouts in manifolds.h)
// and the preintegration from the previous window frame to itself. Frames are heap-allocated so the block
// addresses stay valid while the window slides. Frame ids grow monotonically and never repeat, so the
// marginalisation keys (frame id * 4 + block kind) stay valid without shifting.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/imu/preintegration.h"

namespace linnet {

using FrameId = std::int64_t;

struct WindowFrame {
  FrameId id = 0;
  Timestamp t = 0;
  std::array<double, 7> pose{0, 0, 0, 0, 0, 0, 1};  // T_W_B: p (3), q xyzw (4)
  std::array<double, 9> speed_bias{};               // v_W (3), b_a (3), b_g (3)
  std::unique_ptr<Preintegration> preint;           // previous window frame -> this frame; null for the oldest
  bool keyframe = false;
  Vec3 gyr = Vec3::Zero();                          // measured angular rate at t (mean over the last 10 ms), rad/s
  bool at_rest = false;                             // zero-velocity update detected at this frame
  Pose capture_shift;  // body at the capture time relative to the body at t (a held camera-to-IMU time offset;
                       // identity otherwise): the frame's visual residuals use capture_shift * T_B_C

  Pose T_W_B() const;
  void setPose(const Pose& T);
  Vec3 v() const { return Vec3(speed_bias[0], speed_bias[1], speed_bias[2]); }
  Vec3 ba() const { return Vec3(speed_bias[3], speed_bias[4], speed_bias[5]); }
  Vec3 bg() const { return Vec3(speed_bias[6], speed_bias[7], speed_bias[8]); }
  void setV(const Vec3& v);
  void setBiases(const Vec3& ba, const Vec3& bg);
};

/// Marginalisation / prior keys of a frame's blocks.
enum class BlockKind : int { kPose = 0, kSpeedBias = 1 };
inline std::int64_t frameBlockKey(FrameId id, BlockKind kind) { return id * 4 + static_cast<int>(kind); }

class Window {
 public:
  int size() const { return static_cast<int>(frames_.size()); }
  bool empty() const { return frames_.empty(); }
  WindowFrame& operator[](int i) { return *frames_[static_cast<std::size_t>(i)]; }
  const WindowFrame& operator[](int i) const { return *frames_[static_cast<std::size_t>(i)]; }
  WindowFrame& newest() { return *frames_.back(); }
  const WindowFrame& newest() const { return *frames_.back(); }
  WindowFrame& oldest() { return *frames_.front(); }

  /// Appends a frame with the next id; returns it.
  WindowFrame& push(Timestamp t);
  /// Frame by id, or nullptr if it is not (any more) in the window.
  const WindowFrame* find(FrameId id) const;
  WindowFrame* find(FrameId id);
  /// Index of a frame id in the window, -1 if absent.
  int indexOf(FrameId id) const;
  /// Id of the newest keyframe (excluding the newest frame itself), -1 if there is none.
  FrameId lastKeyframeBefore(int index) const;

  /// Removes the oldest frame; the next frame's preintegration (which starts at the removed frame) is cleared.
  void popOldest();
  /// Removes frame `index` (0 < index < size-1) and merges its preintegration into the next frame's.
  void removeMerging(int index);
  void clear() { frames_.clear(); }

  /// Data-block pointer lookup for keys made by frameBlockKey(); nullptr if the frame is gone.
  double* block(std::int64_t key);

 private:
  std::deque<std::unique_ptr<WindowFrame>> frames_;
  FrameId next_id_ = 0;
};

/// The world -> camera poses of every window frame's cam0 (and cam1), computed once for the checks that reproject
/// all the sightings of the window: the same numbers as inverting T_W_B * T_B_C at each sighting.
class WindowCameras {
 public:
  WindowCameras(const Window& window, const Pose& T_B_C0, const std::optional<Pose>& T_B_C1);
  /// T_C0_W of frame `id`; nullptr if the frame is not in the window.
  const Pose* cam0(FrameId id) const;
  /// T_C1_W of frame `id`; nullptr if the frame is not in the window or there is no cam1.
  const Pose* cam1(FrameId id) const;

 private:
  int index(FrameId id) const;
  std::vector<FrameId> ids_;  // ascending, as in the window
  std::vector<Pose> c0_, c1_;
};

}  // namespace linnet
