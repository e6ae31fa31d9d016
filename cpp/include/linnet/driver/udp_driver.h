// The host driver of the stereo-IMU sensor module (thesis ch. 2): a receive thread that does nothing but recv() into
// a ring buffer, and a parse thread that rebuilds frames and IMU samples from it (FrameAssembler) and hands them to
// callbacks, which run on the parse thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "linnet/driver/frame_assembler.h"
#include "linnet/driver/packet_ring.h"

namespace linnet {

class UdpDriver {
 public:
  /// Binds a UDP socket to host:port (port 0: any free port, see port()) and starts both threads. InputError when the
  /// socket cannot be bound (naming host and port).
  UdpDriver(const SensorOptions& options, const std::string& host, int port, FrameAssembler::ImuCallback on_imu,
            FrameAssembler::FrameCallback on_frame);
  ~UdpDriver();
  UdpDriver(const UdpDriver&) = delete;
  UdpDriver& operator=(const UdpDriver&) = delete;

  int port() const { return port_; }
  /// Stops receiving, parses what the ring holds, flushes the open frame, joins the threads. Idempotent.
  void stop();
  /// Seconds since the last datagram (since start if none yet), and whether any arrived.
  double idleSeconds() const;
  bool receivedAny() const { return received_.load() > 0; }
  /// A snapshot of the counters (the parse thread's, with the ring's and the threads' CPU time).
  DriverCounters counters() const;
  /// Rethrows an exception raised by a callback on the parse thread (the driver stops parsing after one).
  void rethrowError();

 private:
  void receiveLoop();
  void parseLoop();

  SensorOptions options_;
  int socket_ = -1;
  int port_ = 0;
  std::unique_ptr<PacketRing> ring_;
  std::unique_ptr<FrameAssembler> assembler_;
  mutable std::mutex counters_mutex_;  // guards assembler_'s counters against snapshots while parsing
  std::atomic<bool> stop_{false};
  std::atomic<std::uint64_t> received_{0};
  std::atomic<std::int64_t> last_packet_ns_{0};
  std::int64_t start_ns_ = 0;
  std::atomic<double> receive_cpu_s_{0.0}, parse_cpu_s_{0.0};
  std::exception_ptr error_;
  std::thread receiver_, parser_;
  bool stopped_ = false;
};

}  // namespace linnet
