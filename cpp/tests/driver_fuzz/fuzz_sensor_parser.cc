// Fuzz test of the sensor-module packet parser and frame assembler, built with AddressSanitizer and
// UndefinedBehaviorSanitizer (CMake option LINNET_SANITIZER_TESTS; run by ctest on a short budget):
// random datagrams (random bytes, and valid packets with random mutations / truncations / extensions) must be
// counted, never read out of bounds, never crash. Usage: fuzz_sensor_parser [packets] [seed]
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "linnet/driver/frame_assembler.h"
#include "linnet/io/sensor_protocol.h"

int main(int argc, char** argv) {
  const long packets = argc > 1 ? std::atol(argv[1]) : 300000;
  std::mt19937_64 rng(argc > 2 ? std::strtoull(argv[2], nullptr, 10) : 1);
  linnet::SensorOptions o;
  o.width = 24;
  o.height = 12;
  o.incomplete = "fill";
  o.max_lost_rows_fraction = 0.5;
  long frames = 0, samples = 0;
  linnet::FrameAssembler assembler(
      o, [&](const linnet::ImuSample&) { ++samples; },
      [&](const linnet::DriverFrame& f) {
        if (f.left.rows != o.height || f.right.cols != o.width) std::abort();
        ++frames;
      });
  std::uniform_int_distribution<int> byte(0, 255), kind(0, 10);
  std::vector<std::uint8_t> row(static_cast<std::size_t>(o.width), 7);
  long pushed = 0;
  std::uint32_t frame_counter = 0;
  while (pushed < packets) {
    std::vector<std::uint8_t> p;
    const int k = kind(rng);
    if (k == 10) {  // a whole exposure: frame packet and every row, a few rows lost
      linnet::sensor::FramePacket f;
      f.counter = frame_counter++;
      f.imu = {{0, 1000 + 50 * static_cast<std::int64_t>(f.counter)}};
      const auto header = linnet::sensor::encodeFrame(f);
      assembler.push(header.data(), header.size());
      ++pushed;
      for (int r = 0; r < o.height; ++r)
        for (int c = 0; c < 2; ++c) {
          if (rng() % 16 == 0) continue;
          const auto packet = linnet::sensor::encodeRow(c, r, row.data(), o.width);
          assembler.push(packet.data(), packet.size());
          ++pushed;
        }
      continue;
    }
    switch (k) {
      case 0:  // random bytes of random length
        p.resize(static_cast<std::size_t>(rng() % 64));
        for (auto& b : p) b = static_cast<std::uint8_t>(byte(rng));
        break;
      case 1:
      case 2: {
        linnet::sensor::ImuPacket imu;
        imu.counter = static_cast<std::uint32_t>(rng() % 2000);
        imu.t = static_cast<linnet::Timestamp>(rng());
        p = linnet::sensor::encodeImu(imu);
        break;
      }
      case 3: {
        linnet::sensor::FramePacket f;
        f.counter = static_cast<std::uint32_t>(rng() % 50);
        const int n = static_cast<int>(rng() % 5);
        for (int k = 0; k < n; ++k) f.imu.emplace_back(static_cast<std::uint32_t>(k), static_cast<std::int64_t>(rng()));
        p = linnet::sensor::encodeFrame(f);
        break;
      }
      default:  // rows, some out of range
        p = linnet::sensor::encodeRow(static_cast<int>(rng() % 2), static_cast<int>(rng() % (o.height + 3)),
                                      row.data(), o.width);
        break;
    }
    // Mutations: flip bytes, truncate, extend.
    const int m = static_cast<int>(rng() % 8);
    if (m == 0 && !p.empty()) p[rng() % p.size()] = static_cast<std::uint8_t>(byte(rng));
    if (m == 1 && !p.empty()) p.resize(rng() % p.size());
    if (m == 2) p.push_back(static_cast<std::uint8_t>(byte(rng)));
    // An exactly sized buffer, so that any read past the end is a heap overflow the sanitizer reports.
    std::vector<std::uint8_t> exact(p.begin(), p.end());
    assembler.push(exact.empty() ? nullptr : exact.data(), exact.size());
    ++pushed;
  }
  assembler.flush();
  const linnet::DriverCounters& c = assembler.counters();
  if (c.packets != static_cast<std::uint64_t>(pushed)) {
    std::fprintf(stderr, "fuzz_sensor_parser: %llu packets counted, %ld pushed\n",
                 static_cast<unsigned long long>(c.packets), pushed);
    return 1;
  }
  std::printf("fuzz_sensor_parser: %ld packets: %llu bad, %ld frames, %ld IMU samples, no fault\n", pushed,
              static_cast<unsigned long long>(c.bad_packets), frames, samples);
  return 0;
}
