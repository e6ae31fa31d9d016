#include "linnet/driver/packet_ring.h"

#include <algorithm>
#include <chrono>

#include "linnet/core/error.h"

namespace linnet {

PacketRing::PacketRing(std::size_t slots, std::size_t slot_bytes, bool block_when_full)
    : slots_(slots), slot_bytes_(slot_bytes), block_(block_when_full), data_(slots * slot_bytes), sizes_(slots, 0) {
  if (slots < 2 || slot_bytes == 0) throw UsageError("PacketRing: needs at least 2 slots of at least 1 byte");
}

std::uint8_t* PacketRing::beginWrite() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (writing_) throw UsageError("PacketRing: beginWrite twice without commitWrite");
  // The slot being read is counted in count_ until endRead, so a writer never reaches it.
  if (block_) not_full_.wait(lock, [&] { return closed_ || count_ < slots_; });
  if (closed_) return nullptr;
  if (count_ >= slots_) return nullptr;
  writing_ = true;
  return data_.data() + ((head_ + count_) % slots_) * slot_bytes_;
}

void PacketRing::commitWrite(std::size_t size) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!writing_) throw UsageError("PacketRing: commitWrite without beginWrite");
    writing_ = false;
    sizes_[(head_ + count_) % slots_] = size;
    ++count_;
    high_water_ = std::max(high_water_, count_);
  }
  not_empty_.notify_one();
}

const std::uint8_t* PacketRing::beginRead(std::size_t* size, int timeout_ms) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (reading_) throw UsageError("PacketRing: beginRead twice without endRead");
  if (!not_empty_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return closed_ || count_ > 0; }))
    return nullptr;
  if (count_ == 0) return nullptr;  // closed and drained
  reading_ = true;
  *size = sizes_[head_];
  return data_.data() + head_ * slot_bytes_;
}

void PacketRing::endRead() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!reading_) throw UsageError("PacketRing: endRead without beginRead");
    reading_ = false;
    head_ = (head_ + 1) % slots_;
    --count_;
  }
  not_full_.notify_one();
}

void PacketRing::close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    closed_ = true;
  }
  not_empty_.notify_all();
  not_full_.notify_all();
}

void PacketRing::noteOverflow() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++overflows_;
}

bool PacketRing::drained() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return closed_ && count_ == 0;
}

std::uint64_t PacketRing::overflows() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return overflows_;
}

std::size_t PacketRing::highWater() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return high_water_;
}

}  // namespace linnet
