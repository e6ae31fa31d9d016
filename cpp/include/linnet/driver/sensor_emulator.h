// An emulator of the stereo-IMU sensor module: streams a EuRoC folder over UDP in the module's protocol
// (linnet/io/sensor_protocol.h), paced in real time x rate, so that the driver and live runs can be tested on one
// machine.
//
// Timing (data time, mapped to wall time / rate): IMU packets at their time stamps, from imu_lead_s before the first
// image; for each image, at its time stamp, the frame packet, then the rows (cam0 row r, cam1 row r, r = 0..H-1)
// spread evenly over row_spread of the frame interval, with the IMU packets of that interval between them. The frame
// packet lists the IMU samples around the image: the sample at the image's stamp and its two neighbours when the
// image stamp is an IMU stamp (odd count: the frame-stamp rule gives the image stamp exactly; EuRoC's image stamps
// are IMU stamps; the sample alone at an end of the IMU stream), otherwise the two samples around it (even count:
// their mean). Images narrower / shorter than the
// module's W x H are padded with zeros on the right / bottom, larger ones cropped.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "linnet/io/sensor_protocol.h"

namespace linnet {

struct EmulatorOptions {
  std::string host = "127.0.0.1";
  int port = 0;
  double rate = 1.0;         // x real time (> 0)
  double drop_prob = 0.0;    // probability of dropping each packet
  std::uint64_t seed = 0;    // of the drops
  double duration_s = -1.0;  // data time to stream from the first image (< 0: to the last image)
  double imu_lead_s = 1.0;   // IMU before the first image, s
  double row_spread = 0.8;   // fraction of the frame interval over which the rows are sent
  int loops = 1;             // stream the images this many times (time stamps continue): long streams from a
                             // short folder
};

/// One dropped packet.
struct DroppedPacket {
  std::string kind;          // "row", "imu", "frame"
  std::uint32_t frame = 0;   // frame counter (rows, frame packets)
  int camera = -1, row = -1;  // rows
  std::uint32_t imu_counter = 0;  // IMU packets
};

struct EmulatorReport {
  std::uint64_t packets_sent = 0, bytes_sent = 0, packets_dropped = 0;
  std::uint64_t frames = 0, imu_samples = 0;
  std::uint64_t rows_sent[2] = {0, 0};
  std::uint64_t rows_dropped[2] = {0, 0};          // in frames whose frame packet was sent
  std::uint64_t rows_of_headless_frames[2] = {0, 0};  // rows sent in frames whose frame packet was dropped
  std::uint64_t frames_dropped = 0, imu_dropped = 0;
  std::uint64_t frames_with_dropped_rows = 0;      // of the frames whose frame packet was sent
  std::vector<DroppedPacket> dropped;
  double wall_s = 0.0, data_s = 0.0;
  double late_s = 0.0;  // how far behind schedule the sender fell at worst (s)
};

/// Streams the folder. `progress(frames_sent, frames_total)` after each frame. `should_stop()` is polled between
/// packets (e.g. for SIGINT). InputError for an unreadable folder or a socket error.
EmulatorReport emulateDataset(const std::string& dataset, const SensorOptions& sensor, const EmulatorOptions& options,
                              const std::function<void(int, int)>& progress = nullptr,
                              const std::function<bool()>& should_stop = nullptr);

}  // namespace linnet
