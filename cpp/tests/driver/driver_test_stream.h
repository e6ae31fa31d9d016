// A synthetic sensor-module stream for the driver tests: frames of known pixels (value = f(frame, camera, row,
// column)) with their frame packets, and IMU samples.
#pragma once

#include <cstdint>
#include <vector>

#include "linnet/io/sensor_protocol.h"

namespace linnet::driver_test {

inline std::uint8_t pixel(int frame, int camera, int row, int col) {
  return static_cast<std::uint8_t>(frame * 31 + camera * 17 + row * 7 + col);
}

/// The packets of `frames` exposures 50 ms apart, each: 10 IMU samples (5 ms apart), the frame packet (3 IMU samples
/// around the exposure), then cam0 / cam1 rows interleaved.
inline std::vector<std::vector<std::uint8_t>> stream(const SensorOptions& o, int frames) {
  std::vector<std::vector<std::uint8_t>> out;
  std::uint32_t imu_counter = 0;
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(o.width));
  for (int f = 0; f < frames; ++f) {
    const Timestamp t = 1'000'000'000 + f * 50'000'000LL;
    for (int k = 0; k < 10; ++k) {
      ImuSample s;
      s.t = t - 45'000'000 + k * 5'000'000LL;
      s.acc = Vec3(0.1 * k, 0.0, 9.81);
      out.push_back(sensor::encodeImu(sensor::quantise(s, imu_counter++, o)));
    }
    sensor::FramePacket fp;
    fp.counter = static_cast<std::uint32_t>(f);
    fp.imu = {{imu_counter - 2, t - 5'000'000}, {imu_counter - 1, t}, {imu_counter, t + 5'000'000}};
    out.push_back(sensor::encodeFrame(fp));
    for (int r = 0; r < o.height; ++r)
      for (int c = 0; c < 2; ++c) {
        for (int x = 0; x < o.width; ++x) pixels[static_cast<std::size_t>(x)] = pixel(f, c, r, x);
        out.push_back(sensor::encodeRow(c, r, pixels.data(), o.width));
      }
  }
  return out;
}

}  // namespace linnet::driver_test
