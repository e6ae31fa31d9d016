#include "linnet/io/sensor_protocol.h"

#include <algorithm>
#include <cmath>

namespace linnet::sensor {

namespace {

constexpr double kG = 9.80665;  // m/s^2 per g (the unit of the accelerometer range)
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

void putU32(std::vector<std::uint8_t>& b, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void putI64(std::vector<std::uint8_t>& b, Timestamp v) {
  const auto u = static_cast<std::uint64_t>(v);
  for (int i = 0; i < 8; ++i) b.push_back(static_cast<std::uint8_t>(u >> (8 * i)));
}
std::uint32_t getU32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
Timestamp getI64(const std::uint8_t* p) {
  std::uint64_t u = 0;
  for (int i = 7; i >= 0; --i) u = (u << 8) | p[i];
  return static_cast<Timestamp>(u);
}

std::int16_t toRaw(double value, double full_scale) {
  const double r = std::round(value / full_scale * 32768.0);
  return static_cast<std::int16_t>(std::clamp(r, -32768.0, 32767.0));
}

}  // namespace

std::optional<Timestamp> frameStamp(const FramePacket& frame) {
  const std::size_t n = frame.imu.size();
  if (n == 0) return std::nullopt;
  if (n % 2 == 1) return frame.imu[n / 2].second;
  const Timestamp a = frame.imu[n / 2 - 1].second, b = frame.imu[n / 2].second;
  return a / 2 + b / 2 + (a % 2 + b % 2) / 2;  // the mean (rounded toward zero), without overflow for any stamps
}

ImuPacket quantise(const ImuSample& s, std::uint32_t counter, const SensorOptions& o) {
  ImuPacket p;
  p.counter = counter;
  p.t = s.t;
  for (int k = 0; k < 3; ++k) {
    p.raw[k] = toRaw(s.acc[k], o.acc_range_g * kG);
    p.raw[3 + k] = toRaw(s.gyr[k], o.gyr_range_dps * kDegToRad);
  }
  return p;
}

ImuSample dequantise(const ImuPacket& p, const SensorOptions& o) {
  ImuSample s;
  s.t = p.t;
  for (int k = 0; k < 3; ++k) {
    s.acc[k] = p.raw[k] / 32768.0 * o.acc_range_g * kG;
    s.gyr[k] = p.raw[3 + k] / 32768.0 * o.gyr_range_dps * kDegToRad;
  }
  return s;
}

std::vector<std::uint8_t> encodeRow(int camera, int row, const std::uint8_t* pixels, int width) {
  std::vector<std::uint8_t> b;
  b.reserve(3 + static_cast<std::size_t>(width));
  b.push_back(static_cast<std::uint8_t>(camera));
  b.push_back(static_cast<std::uint8_t>(row & 0xFF));
  b.push_back(static_cast<std::uint8_t>((row >> 8) & 0xFF));
  b.insert(b.end(), pixels, pixels + width);
  return b;
}

std::vector<std::uint8_t> encodeImu(const ImuPacket& p) {
  std::vector<std::uint8_t> b;
  b.reserve(kImuPacketSize);
  b.push_back(kImuType);
  putU32(b, p.counter);
  putI64(b, p.t);
  for (std::int16_t v : p.raw) {
    const auto u = static_cast<std::uint16_t>(v);
    b.push_back(static_cast<std::uint8_t>(u >> 8));    // high byte first
    b.push_back(static_cast<std::uint8_t>(u & 0xFF));  // then low byte
  }
  return b;
}

std::vector<std::uint8_t> encodeFrame(const FramePacket& f) {
  std::vector<std::uint8_t> b;
  const std::size_t n = std::min<std::size_t>(f.imu.size(), 255);
  b.reserve(kFrameHeaderSize + kFrameEntrySize * n);
  b.push_back(kFrameType);
  putU32(b, f.counter);
  b.push_back(static_cast<std::uint8_t>(n));
  for (std::size_t i = 0; i < n; ++i) {
    putU32(b, f.imu[i].first);
    putI64(b, f.imu[i].second);
  }
  return b;
}

DecodedPacket decode(const std::uint8_t* data, std::size_t size, const SensorOptions& o) {
  DecodedPacket d;
  if (data == nullptr || size == 0) {
    d.reason = "empty packet";
    return d;
  }
  const std::uint8_t type = data[0];
  if (type == 0 || type == 1) {
    if (size != 3 + static_cast<std::size_t>(o.width)) {
      d.reason = size < 3 + static_cast<std::size_t>(o.width) ? "short row packet" : "long row packet";
      return d;
    }
    const int row = data[1] | (data[2] << 8);
    if (row >= o.height) {
      d.reason = "row number out of range";
      return d;
    }
    d.kind = PacketKind::kRow;
    d.camera = type;
    d.row = row;
    d.pixels = data + 3;
    return d;
  }
  if (type == kImuType) {
    if (size != kImuPacketSize) {
      d.reason = "IMU packet of wrong length";
      return d;
    }
    d.imu.counter = getU32(data + 1);
    d.imu.t = getI64(data + 5);
    for (int k = 0; k < 6; ++k)
      d.imu.raw[k] = static_cast<std::int16_t>(static_cast<std::uint16_t>((data[13 + 2 * k] << 8) | data[14 + 2 * k]));
    d.kind = PacketKind::kImu;
    return d;
  }
  if (type == kFrameType) {
    if (size < kFrameHeaderSize) {
      d.reason = "short frame packet";
      return d;
    }
    const std::size_t n = data[5];
    if (size != kFrameHeaderSize + kFrameEntrySize * n) {
      d.reason = "frame packet of wrong length";
      return d;
    }
    d.frame.counter = getU32(data + 1);
    d.frame.imu.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint8_t* e = data + kFrameHeaderSize + kFrameEntrySize * i;
      d.frame.imu.emplace_back(getU32(e), getI64(e + 4));
    }
    d.kind = PacketKind::kFrame;
    return d;
  }
  d.reason = "unknown packet type";
  return d;
}

}  // namespace linnet::sensor
