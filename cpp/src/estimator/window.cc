#include "linnet/estimator/window.h"

#include <algorithm>

#include "linnet/core/error.h"
#include "linnet/estimator/manifolds.h"

namespace linnet {

Pose WindowFrame::T_W_B() const { return poseFromBlock(pose.data()); }
void WindowFrame::setPose(const Pose& T) { linnet::setPose(T, pose.data()); }
void WindowFrame::setV(const Vec3& v) {
  for (int k = 0; k < 3; ++k) speed_bias[static_cast<std::size_t>(k)] = v[k];
}
void WindowFrame::setBiases(const Vec3& ba, const Vec3& bg) {
  for (int k = 0; k < 3; ++k) {
    speed_bias[static_cast<std::size_t>(3 + k)] = ba[k];
    speed_bias[static_cast<std::size_t>(6 + k)] = bg[k];
  }
}

WindowFrame& Window::push(Timestamp t) {
  auto f = std::make_unique<WindowFrame>();
  f->id = next_id_++;
  f->t = t;
  frames_.push_back(std::move(f));
  return *frames_.back();
}

const WindowFrame* Window::find(FrameId id) const {
  const int i = indexOf(id);
  return i < 0 ? nullptr : frames_[static_cast<std::size_t>(i)].get();
}
WindowFrame* Window::find(FrameId id) {
  const int i = indexOf(id);
  return i < 0 ? nullptr : frames_[static_cast<std::size_t>(i)].get();
}

int Window::indexOf(FrameId id) const {
  // Ids increase along the window: binary search.
  int lo = 0, hi = size() - 1;
  while (lo <= hi) {
    const int mid = (lo + hi) / 2;
    const FrameId m = frames_[static_cast<std::size_t>(mid)]->id;
    if (m == id) return mid;
    if (m < id)
      lo = mid + 1;
    else
      hi = mid - 1;
  }
  return -1;
}

FrameId Window::lastKeyframeBefore(int index) const {
  for (int i = index - 1; i >= 0; --i)
    if ((*this)[i].keyframe) return (*this)[i].id;
  return -1;
}

void Window::popOldest() {
  if (frames_.empty()) throw UsageError("Window::popOldest: the window is empty");
  frames_.pop_front();
  if (!frames_.empty()) frames_.front()->preint.reset();
}

void Window::removeMerging(int index) {
  if (index <= 0 || index >= size() - 1)
    throw UsageError("Window::removeMerging: index " + std::to_string(index) + " is not an inner frame");
  WindowFrame& gone = (*this)[index];
  WindowFrame& next = (*this)[index + 1];
  if (gone.preint && next.preint) {
    gone.preint->append(*next.preint);
    next.preint = std::move(gone.preint);
  }
  frames_.erase(frames_.begin() + index);
}

double* Window::block(std::int64_t key) {
  WindowFrame* f = find(key / 4);
  if (f == nullptr) return nullptr;
  return key % 4 == static_cast<int>(BlockKind::kPose) ? f->pose.data() : f->speed_bias.data();
}

WindowCameras::WindowCameras(const Window& window, const Pose& T_B_C0, const std::optional<Pose>& T_B_C1) {
  ids_.reserve(static_cast<std::size_t>(window.size()));
  c0_.reserve(static_cast<std::size_t>(window.size()));
  for (int i = 0; i < window.size(); ++i) {
    const WindowFrame& f = window[i];
    const Pose T_W_B = f.T_W_B();
    ids_.push_back(f.id);
    c0_.push_back((T_W_B * T_B_C0).inverse());
    if (T_B_C1) c1_.push_back((T_W_B * *T_B_C1).inverse());
  }
}

int WindowCameras::index(FrameId id) const {
  const auto it = std::lower_bound(ids_.begin(), ids_.end(), id);
  return it == ids_.end() || *it != id ? -1 : static_cast<int>(it - ids_.begin());
}

const Pose* WindowCameras::cam0(FrameId id) const {
  const int i = index(id);
  return i < 0 ? nullptr : &c0_[static_cast<std::size_t>(i)];
}

const Pose* WindowCameras::cam1(FrameId id) const {
  const int i = index(id);
  return i < 0 || c1_.empty() ? nullptr : &c1_[static_cast<std::size_t>(i)];
}

}  // namespace linnet
