// Factor objects reused from one window solve to the next.
//
// A window solve builds a few thousand visual factors, each a Ceres cost function: its own heap block plus the
// parameter-size vector Ceres keeps in the base class. Built anew every frame, those allocations were about 40 % of
// the process's calls to malloc. The pool keeps the objects of the last set it handed out and, once nothing holds
// them any more, re-initialises them in place (T::reset with the constructor's arguments) for the next set.
#pragma once

#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

namespace linnet {

template <class T>
class FactorPool {
 public:
  /// Starts a new set. The objects of the previous set are reused only if no pointer to any of them is left (the
  /// set is one shared block: a residual kept elsewhere keeps its whole set alive, and the pool starts a new one).
  void begin() {
    if (!set_ || set_.use_count() > 1) set_ = std::make_shared<Set>();
    used_ = 0;
  }

  /// A factor built from `args` (T(args...) or, for a reused object, T::reset(args...)), valid as long as the
  /// returned pointer or any other of its set is held.
  template <class... Args>
  std::shared_ptr<T> make(Args&&... args) {
    if (!set_) begin();
    std::vector<std::unique_ptr<T>>& objects = set_->objects;
    if (used_ == objects.size())
      objects.push_back(std::make_unique<T>(std::forward<Args>(args)...));
    else
      objects[used_]->reset(std::forward<Args>(args)...);
    return std::shared_ptr<T>(set_, objects[used_++].get());  // shares the set's ownership: no allocation
  }

  /// Objects kept for reuse.
  std::size_t capacity() const { return set_ ? set_->objects.size() : 0; }

 private:
  struct Set {
    std::vector<std::unique_ptr<T>> objects;
  };
  std::shared_ptr<Set> set_;
  std::size_t used_ = 0;
};

}  // namespace linnet
