// The index of a solver's parameter blocks by their data pointer: an open-addressing hash table (linear probing) in
// one array, which doubles as blocks are added (clear() keeps it for a next problem). A solve registers a few hundred
// blocks and looks each residual's blocks up; a node-based std::unordered_map paid one heap allocation per block (8 %
// of the process's calls to malloc).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace linnet {

class BlockIndex {
 public:
  /// The value stored for `key`, or -1.
  int find(const double* key) const {
    if (slots_.empty()) return -1;
    for (std::size_t i = home(key);; i = (i + 1) & mask_) {
      const Slot& s = slots_[i];
      if (s.key == key) return s.value;
      if (s.key == nullptr) return -1;
    }
  }

  /// Stores `value` (>= 0) for `key` (not null); false, and nothing changed, if `key` is already there.
  bool insert(const double* key, int value) {
    if (2 * (size_ + 1) > slots_.size()) grow();
    for (std::size_t i = home(key);; i = (i + 1) & mask_) {
      Slot& s = slots_[i];
      if (s.key == key) return false;
      if (s.key == nullptr) {
        s = {key, value};
        ++size_;
        return true;
      }
    }
  }

  /// Empties the index; its array stays allocated for the next problem.
  void clear() {
    if (size_ == 0) return;
    for (Slot& s : slots_) s = Slot{};
    size_ = 0;
  }

  std::size_t size() const { return size_; }

 private:
  struct Slot {
    const double* key = nullptr;
    int value = -1;
  };

  // Fibonacci hashing of the pointer (its low 3 bits are 0 for doubles): the top bits of the product.
  std::size_t home(const double* key) const {
    const auto bits = static_cast<std::uint64_t>(reinterpret_cast<std::uintptr_t>(key)) >> 3;
    return static_cast<std::size_t>((bits * 0x9E3779B97F4A7C15ull) >> shift_);
  }

  // Doubles the array (at least 64 slots) and re-inserts the entries: the load stays at most one half.
  void grow() {
    std::vector<Slot> old;
    old.swap(slots_);
    const std::size_t capacity = old.empty() ? 64 : 2 * old.size();
    slots_.assign(capacity, Slot{});
    mask_ = capacity - 1;
    shift_ = 64;
    for (std::size_t c = capacity; c > 1; c >>= 1) --shift_;
    size_ = 0;
    for (const Slot& s : old)
      if (s.key != nullptr) insert(s.key, s.value);
  }

  std::vector<Slot> slots_;
  std::size_t mask_ = 0;
  int shift_ = 64;
  std::size_t size_ = 0;
};

}  // namespace linnet
