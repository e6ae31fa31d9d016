// The UDP driver end to end on the loopback interface: a synthetic module stream sent by a socket, frames and IMU
// samples out of the parse thread, counters, and a clean stop.
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

#include "driver/driver_test_stream.h"
#include "linnet/core/error.h"
#include "linnet/driver/udp_driver.h"

namespace linnet {
namespace {

TEST(UdpDriver, LoopbackStreamArrivesWhole) {
  SensorOptions o;
  o.width = 320;
  o.height = 60;
  std::mutex m;
  std::vector<Timestamp> frame_stamps;
  std::atomic<int> samples{0};
  UdpDriver driver(
      o, "127.0.0.1", 0, [&](const ImuSample&) { ++samples; },
      [&](const DriverFrame& f) {
        std::lock_guard<std::mutex> lock(m);
        frame_stamps.push_back(f.t);
      });
  ASSERT_GT(driver.port(), 0);
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<std::uint16_t>(driver.port()));
  ::inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  const auto packets = driver_test::stream(o, 30);
  std::size_t i = 0;
  for (const auto& p : packets) {
    ::sendto(fd, p.data(), p.size(), 0, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
    if (++i % 200 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1));  // about 200k packets/s at most
  }
  const std::uint8_t garbage[3] = {0x42, 1, 2};
  ::sendto(fd, garbage, sizeof garbage, 0, reinterpret_cast<const sockaddr*>(&addr), sizeof addr);
  ::close(fd);
  for (int wait = 0; wait < 200 && driver.counters().packets < packets.size() + 1; ++wait)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  driver.stop();
  driver.rethrowError();
  const DriverCounters c = driver.counters();
  EXPECT_EQ(c.packets, packets.size() + 1);
  EXPECT_EQ(c.bad_packets, 1u);
  EXPECT_EQ(c.frames_complete, 30u);
  EXPECT_EQ(c.lost_rows[0] + c.lost_rows[1] + c.ring_overflows, 0u);
  EXPECT_EQ(samples.load(), 300);
  ASSERT_EQ(frame_stamps.size(), 30u);
  for (int f = 0; f < 30; ++f) EXPECT_EQ(frame_stamps[f], 1'000'000'000 + f * 50'000'000LL);
  EXPECT_GT(c.parse_cpu_s, 0.0);
}

TEST(UdpDriver, BadAddressIsAnInputError) {
  SensorOptions o;
  EXPECT_THROW(UdpDriver(o, "not-an-ip", 0, nullptr, nullptr), InputError);
}

}  // namespace
}  // namespace linnet
