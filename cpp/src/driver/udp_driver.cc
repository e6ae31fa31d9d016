#include "linnet/driver/udp_driver.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "linnet/core/cpu_clock.h"
#include "linnet/core/error.h"

namespace linnet {

namespace {

std::int64_t nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

constexpr int kPollMs = 50;  // how often the threads look at the stop flag

}  // namespace

UdpDriver::UdpDriver(const SensorOptions& options, const std::string& host, int port,
                     FrameAssembler::ImuCallback on_imu, FrameAssembler::FrameCallback on_frame)
    : options_(options), start_ns_(nowNs()) {
  const std::string where = "udp://" + host + ":" + std::to_string(port);
  socket_ = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (socket_ < 0) throw InputError(where + ": cannot create a UDP socket: " + std::strerror(errno));
  // As large a receive buffer as allowed (root may exceed net.core.rmem_max with SO_RCVBUFFORCE).
  const int bytes = options_.receive_buffer_bytes;
  if (::setsockopt(socket_, SOL_SOCKET, SO_RCVBUFFORCE, &bytes, sizeof bytes) != 0)
    ::setsockopt(socket_, SOL_SOCKET, SO_RCVBUF, &bytes, sizeof bytes);
  timeval tv{0, kPollMs * 1000};
  ::setsockopt(socket_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::inet_pton(AF_INET, host.c_str(), &addr.sin_addr) != 1) {
    ::close(socket_);
    throw InputError(where + ": not an IPv4 address");
  }
  if (::bind(socket_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    const std::string why = std::strerror(errno);
    ::close(socket_);
    throw InputError(where + ": cannot bind: " + why);
  }
  socklen_t len = sizeof addr;
  ::getsockname(socket_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = ntohs(addr.sin_port);

  // Slots large enough for the longest valid packet plus one byte, so that an over-long datagram is seen as such.
  const std::size_t slot = std::max<std::size_t>(3 + static_cast<std::size_t>(options_.width),
                                                 sensor::kFrameHeaderSize + 255 * sensor::kFrameEntrySize) + 1;
  ring_ = std::make_unique<PacketRing>(static_cast<std::size_t>(options_.ring_slots), slot,
                                       options_.overflow == "block");
  assembler_ = std::make_unique<FrameAssembler>(options_, std::move(on_imu), std::move(on_frame));
  last_packet_ns_ = start_ns_;
  receiver_ = std::thread([this] { receiveLoop(); });
  parser_ = std::thread([this] { parseLoop(); });
}

UdpDriver::~UdpDriver() {
  try {
    stop();
  } catch (...) {  // a destructor must not throw; stop() only rethrows nothing itself
  }
}

void UdpDriver::receiveLoop() {
  const double cpu0 = threadCpuMs();
  std::uint8_t scratch[1];
  while (!stop_.load()) {
    std::uint8_t* slot = ring_->beginWrite();
    if (slot == nullptr) {
      if (stop_.load()) break;
      // Ring full under the drop policy: take the datagram off the socket and let it go (counted).
      if (::recv(socket_, scratch, sizeof scratch, MSG_TRUNC) >= 0) {
        ++received_;
        last_packet_ns_ = nowNs();
        ring_->noteOverflow();
      }
      continue;
    }
    const ssize_t n = ::recv(socket_, slot, ring_->slotBytes(), MSG_TRUNC);
    if (n < 0) {
      ring_->commitWrite(0);  // nothing received (timeout): an empty slot the parser skips
      continue;
    }
    ++received_;
    last_packet_ns_ = nowNs();
    ring_->commitWrite(static_cast<std::size_t>(n));  // MSG_TRUNC: n is the datagram's length, > slot = too long
  }
  receive_cpu_s_ = 1e-3 * (threadCpuMs() - cpu0);
  ring_->close();
}

void UdpDriver::parseLoop() {
  const double cpu0 = threadCpuMs();
  for (;;) {
    std::size_t size = 0;
    const std::uint8_t* p = ring_->beginRead(&size, kPollMs);
    if (p == nullptr) {
      if (ring_->drained()) break;
      continue;
    }
    if (size > 0 && !error_) {
      std::lock_guard<std::mutex> lock(counters_mutex_);
      try {
        if (size > ring_->slotBytes()) {
          assembler_->pushOversized(size);
        } else {
          assembler_->push(p, size);
        }
      } catch (...) {
        error_ = std::current_exception();
      }
    }
    ring_->endRead();
  }
  parse_cpu_s_ = 1e-3 * (threadCpuMs() - cpu0);
}

void UdpDriver::stop() {
  if (stopped_) return;
  stopped_ = true;
  stop_ = true;
  if (receiver_.joinable()) receiver_.join();
  if (parser_.joinable()) parser_.join();
  {
    std::lock_guard<std::mutex> lock(counters_mutex_);
    if (!error_) {
      try {
        assembler_->flush();
      } catch (...) {
        error_ = std::current_exception();
      }
    }
  }
  if (socket_ >= 0) ::close(socket_);
  socket_ = -1;
}

double UdpDriver::idleSeconds() const { return 1e-9 * static_cast<double>(nowNs() - last_packet_ns_.load()); }

DriverCounters UdpDriver::counters() const {
  DriverCounters c;
  {
    std::lock_guard<std::mutex> lock(counters_mutex_);
    c = assembler_->counters();
  }
  c.ring_overflows = ring_->overflows();
  c.ring_high_water = ring_->highWater();
  c.receive_cpu_s = receive_cpu_s_.load();
  c.parse_cpu_s = parse_cpu_s_.load();
  return c;
}

void UdpDriver::rethrowError() {
  std::exception_ptr e;
  {
    std::lock_guard<std::mutex> lock(counters_mutex_);
    e = error_;
  }
  if (e) std::rethrow_exception(e);
}

}  // namespace linnet
