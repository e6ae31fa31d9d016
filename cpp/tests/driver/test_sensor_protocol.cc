// The sensor module's wire protocol: encoding / decoding, the frame-stamp rule, IMU scaling, bad packets.
#include <gtest/gtest.h>

#include <cmath>

#include "linnet/io/sensor_protocol.h"

namespace linnet {
namespace {

SensorOptions small() {
  SensorOptions o;
  o.width = 8;
  o.height = 4;
  return o;
}

TEST(SensorProtocol, FrameStampRuleOnOddAndEvenCounts) {
  sensor::FramePacket f;
  EXPECT_FALSE(sensor::frameStamp(f).has_value());
  f.imu = {{7, 100}};
  EXPECT_EQ(*sensor::frameStamp(f), 100);
  f.imu = {{7, 100}, {8, 105}, {9, 110}};  // odd: the middle sample
  EXPECT_EQ(*sensor::frameStamp(f), 105);
  f.imu = {{7, 100}, {8, 105}};  // even: the mean of the middle two
  EXPECT_EQ(*sensor::frameStamp(f), 102);
  f.imu = {{1, 100}, {2, 104}, {3, 110}, {4, 120}};
  EXPECT_EQ(*sensor::frameStamp(f), 107);
  f.imu = {{1, 1403715273262142976}, {2, 1403715273267143168}};  // large stamps: no overflow
  EXPECT_EQ(*sensor::frameStamp(f), 1403715273264643072);
}

TEST(SensorProtocol, PacketsRoundTrip) {
  const SensorOptions o = small();
  const std::uint8_t pixels[8] = {1, 2, 3, 4, 250, 251, 252, 253};
  const auto row = sensor::encodeRow(1, 3, pixels, o.width);
  ASSERT_EQ(row.size(), 11u);
  auto d = sensor::decode(row.data(), row.size(), o);
  ASSERT_EQ(d.kind, sensor::PacketKind::kRow);
  EXPECT_EQ(d.camera, 1);
  EXPECT_EQ(d.row, 3);
  EXPECT_EQ(d.pixels[4], 250);

  ImuSample s;
  s.t = 1403715273262142976;
  s.acc = Vec3(9.81, -0.5, 1.25);
  s.gyr = Vec3(0.1, -0.2, 0.3);
  const auto imu = sensor::encodeImu(sensor::quantise(s, 42, o));
  ASSERT_EQ(imu.size(), sensor::kImuPacketSize);
  d = sensor::decode(imu.data(), imu.size(), o);
  ASSERT_EQ(d.kind, sensor::PacketKind::kImu);
  EXPECT_EQ(d.imu.counter, 42u);
  EXPECT_EQ(d.imu.t, s.t);
  const ImuSample back = sensor::dequantise(d.imu, o);
  const double acc_step = o.acc_range_g * 9.80665 / 32768.0, gyr_step = o.gyr_range_dps * M_PI / 180.0 / 32768.0;
  EXPECT_LE((back.acc - s.acc).cwiseAbs().maxCoeff(), 0.5 * acc_step + 1e-12);
  EXPECT_LE((back.gyr - s.gyr).cwiseAbs().maxCoeff(), 0.5 * gyr_step + 1e-12);

  sensor::FramePacket f;
  f.counter = 9;
  f.imu = {{41, 10}, {42, 20}, {43, 30}};
  const auto frame = sensor::encodeFrame(f);
  ASSERT_EQ(frame.size(), sensor::kFrameHeaderSize + 3 * sensor::kFrameEntrySize);
  d = sensor::decode(frame.data(), frame.size(), o);
  ASSERT_EQ(d.kind, sensor::PacketKind::kFrame);
  EXPECT_EQ(d.frame.counter, 9u);
  EXPECT_EQ(d.frame.imu, f.imu);
}

TEST(SensorProtocol, ImuAxesAreHighThenLowByteAndSaturate) {
  const SensorOptions o = small();
  ImuSample s;
  s.acc = Vec3(1000.0, -1000.0, 0.0);  // beyond +-2 g
  const sensor::ImuPacket p = sensor::quantise(s, 0, o);
  EXPECT_EQ(p.raw[0], 32767);
  EXPECT_EQ(p.raw[1], -32768);
  sensor::ImuPacket q;
  q.raw[3] = 0x1234;
  const auto bytes = sensor::encodeImu(q);
  EXPECT_EQ(bytes[13 + 6], 0x12);  // gx high byte
  EXPECT_EQ(bytes[14 + 6], 0x34);  // gx low byte
}

TEST(SensorProtocol, BadPacketsAreClassifiedNotRead) {
  const SensorOptions o = small();
  const std::uint8_t short_row[5] = {0, 1, 0, 9, 9};
  EXPECT_EQ(sensor::decode(short_row, sizeof short_row, o).kind, sensor::PacketKind::kBad);
  std::vector<std::uint8_t> long_row(12, 0);
  EXPECT_STREQ(sensor::decode(long_row.data(), long_row.size(), o).reason, "long row packet");
  std::vector<std::uint8_t> row(11, 0);
  row[1] = 4;  // row 4 of a 4-row image
  EXPECT_STREQ(sensor::decode(row.data(), row.size(), o).reason, "row number out of range");
  const std::uint8_t unknown[3] = {0x42, 0, 0};
  EXPECT_STREQ(sensor::decode(unknown, sizeof unknown, o).reason, "unknown packet type");
  const std::uint8_t imu[10] = {sensor::kImuType};
  EXPECT_EQ(sensor::decode(imu, sizeof imu, o).kind, sensor::PacketKind::kBad);
  const std::uint8_t frame[7] = {sensor::kFrameType, 0, 0, 0, 0, 2, 0};  // says 2 entries, has none
  EXPECT_EQ(sensor::decode(frame, sizeof frame, o).kind, sensor::PacketKind::kBad);
  EXPECT_EQ(sensor::decode(nullptr, 0, o).kind, sensor::PacketKind::kBad);
}

}  // namespace
}  // namespace linnet
