// Bounded single-producer / single-consumer ring of datagrams (thesis ch. 2: the receive thread only receives into
// the ring; the parse thread consumes it). Fixed-size slots are allocated once: the producer receives straight into a
// slot (beginWrite / commitWrite), the consumer reads one in place (beginRead / endRead). A mutex and two condition
// variables hand slots over; when the ring is full the producer either drops the packet (counted) or blocks, per the
// policy. Never corrupts: a slot is never written while it is being read.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <vector>

namespace linnet {

class PacketRing {
 public:
  /// `slots` packets of at most `slot_bytes` each. `block_when_full`: beginWrite waits for room instead of failing.
  PacketRing(std::size_t slots, std::size_t slot_bytes, bool block_when_full);

  /// A free slot to receive into (slot_bytes long), or nullptr when the ring is full and the policy is to drop, or
  /// the ring was closed. A producer that then discards a packet reports it with noteOverflow().
  std::uint8_t* beginWrite();
  void noteOverflow();
  /// Publishes the slot from beginWrite. `size` is the datagram's length as received; it may exceed slotBytes() (a
  /// truncated, over-long datagram: the reader sees the true length and only slotBytes() bytes).
  void commitWrite(std::size_t size);

  /// The oldest packet (pointer and size), waiting up to `timeout_ms`; nullptr on timeout or when closed and empty.
  const std::uint8_t* beginRead(std::size_t* size, int timeout_ms);
  /// Releases the slot from beginRead.
  void endRead();

  /// Wakes every waiter; afterwards writes fail and reads drain what is left.
  void close();
  /// Closed and nothing left to read.
  bool drained() const;

  std::size_t slotBytes() const { return slot_bytes_; }
  std::size_t capacity() const { return slots_; }
  std::uint64_t overflows() const;
  std::size_t highWater() const;  // most packets ever queued at once

 private:
  const std::size_t slots_, slot_bytes_;
  const bool block_;
  std::vector<std::uint8_t> data_;
  std::vector<std::size_t> sizes_;
  mutable std::mutex mutex_;
  std::condition_variable not_empty_, not_full_;
  std::size_t head_ = 0;   // next slot to read
  std::size_t count_ = 0;  // published packets
  bool writing_ = false, reading_ = false, closed_ = false;
  std::uint64_t overflows_ = 0;
  std::size_t high_water_ = 0;
};

}  // namespace linnet
