// Wire protocol of the stereo-IMU sensor module (thesis ch. 2; docs/sensor_protocol.md): UDP datagrams of three
// kinds, told apart by their first byte.
//
//   image row  [camera id 0|1][row lo][row hi][W pixels]                      3 + W bytes (thesis: W = 1280)
//   IMU        [0xA5][counter u32 LE][t ns i64 LE][ax hi lo][ay][az][gx][gy][gz]   25 bytes; int16 = (hi << 8) | lo
//   frame      [0xF5][frame counter u32 LE][n u8][n x (IMU counter u32 LE, t ns i64 LE)]   6 + 12 n bytes
//
// The frame packet opens an exposure: the rows that follow it (both cameras) belong to that frame, and it lists the
// IMU samples seen during the exposure; the frame's time stamp is the middle sample's time for an odd count and the
// mean of the middle two for an even count (frameStamp). Pure functions: no sockets, no threads.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "linnet/core/types.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

/// The module's stream format and the host driver's settings (config section `sensor`).
struct SensorOptions {
  int width = 1280;               // image row length W, pixels (thesis: 1280)
  int height = 720;               // rows per image H (thesis: 720)
  double acc_range_g = 2.0;       // accelerometer full scale, +- g (BMI160 default); int16 32768 = range
  double gyr_range_dps = 2000.0;  // gyroscope full scale, +- deg/s (BMI160 default)
  int ring_slots = 16384;         // driver ring buffer, packets
  std::string overflow = "drop";  // full ring: "drop" the packet (counted) or "block" the receive thread
  std::string incomplete = "drop";  // frame with lost rows: "drop" it or "fill" (lost rows copied from the row
                                    // above, flagged) when at most max_lost_rows_fraction of a camera's rows are lost
  double max_lost_rows_fraction = 0.05;  // "fill" limit per camera (above: dropped), fraction of H
  int receive_buffer_bytes = 64 << 20;   // socket receive buffer (SO_RCVBUF), bytes
  double idle_timeout_s = 2.0;    // live run ends after this long without a packet (once some arrived), s

  template <class V>
  void visit(V& v) {
    v("width", width, "image row length W, pixels", 1, 65000);
    v("height", height, "rows per image H", 1, 65535);
    v("acc_range_g", acc_range_g, "accelerometer full scale, +- g", 0.1, 1000.0);
    v("gyr_range_dps", gyr_range_dps, "gyroscope full scale, +- deg/s", 1.0, 100000.0);
    v("ring_slots", ring_slots, "driver ring buffer size, packets", 16, 10000000);
    v.choice("overflow", overflow, "when the ring buffer is full", {"drop", "block"});
    v.choice("incomplete", incomplete, "frames with lost rows", {"drop", "fill"});
    v("max_lost_rows_fraction", max_lost_rows_fraction, "most lost rows per camera that 'fill' repairs", 0.0, 1.0);
    v("receive_buffer_bytes", receive_buffer_bytes, "socket receive buffer, bytes", 65536, 1 << 30);
    v("idle_timeout_s", idle_timeout_s, "live run ends after this long without packets, s", 0.01, 3600.0);
  }
};

namespace sensor {

constexpr std::uint8_t kImuType = 0xA5;
constexpr std::uint8_t kFrameType = 0xF5;
constexpr std::size_t kImuPacketSize = 25;
constexpr std::size_t kFrameHeaderSize = 6;
constexpr std::size_t kFrameEntrySize = 12;

/// An IMU sample as sent: counter, time stamp and raw int16 axes (acc then gyr).
struct ImuPacket {
  std::uint32_t counter = 0;
  Timestamp t = 0;
  std::int16_t raw[6] = {0, 0, 0, 0, 0, 0};
};

/// A frame packet: counter and the IMU samples (counter, time) seen during the exposure.
struct FramePacket {
  std::uint32_t counter = 0;
  std::vector<std::pair<std::uint32_t, Timestamp>> imu;
};

/// The frame's time stamp from its exposure's IMU samples: the middle one's time for an odd count, the mean of the
/// middle two for an even count (rounded down to the ns); nullopt for none.
std::optional<Timestamp> frameStamp(const FramePacket& frame);

/// SI values -> raw int16 (rounded, saturated) and back, with the ranges of `o`.
ImuPacket quantise(const ImuSample& s, std::uint32_t counter, const SensorOptions& o);
ImuSample dequantise(const ImuPacket& p, const SensorOptions& o);

std::vector<std::uint8_t> encodeRow(int camera, int row, const std::uint8_t* pixels, int width);
std::vector<std::uint8_t> encodeImu(const ImuPacket& p);
std::vector<std::uint8_t> encodeFrame(const FramePacket& f);

/// What a datagram is. Decoding never reads past `size` and never throws: bad packets are kBad with a reason.
enum class PacketKind { kRow, kImu, kFrame, kBad };
struct DecodedPacket {
  PacketKind kind = PacketKind::kBad;
  int camera = -1;                    // kRow
  int row = -1;                       // kRow
  const std::uint8_t* pixels = nullptr;  // kRow: width bytes inside the datagram
  ImuPacket imu;                      // kImu
  FramePacket frame;                  // kFrame
  const char* reason = "";            // kBad: "unknown type", "short row", ...
};
DecodedPacket decode(const std::uint8_t* data, std::size_t size, const SensorOptions& o);

}  // namespace sensor
}  // namespace linnet
