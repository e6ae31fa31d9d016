// The parse side of the sensor-module driver: datagrams in, IMU samples and stereo frames out (thesis ch. 2).
//
// A frame packet opens an exposure; the row packets after it fill that frame's two images by row number. A frame is
// delivered as soon as both images are complete, or, when the next frame packet arrives first, handled by the
// incomplete-frame policy (SensorOptions::incomplete): dropped, or delivered with each lost row copied from the
// nearest received row above (below for row 0) and flagged, if a camera lost at most max_lost_rows_fraction of its
// rows. The module sends each camera's rows in increasing order, so a row number below the last one received for
// that camera means a new exposure whose frame packet was lost: the open frame is closed and the rows up to the next
// frame packet are orphans, as are rows with no open frame at all. A row received twice in a row is a duplicate. IMU samples are delivered in counter order as they arrive; a gap in the
// counter counts lost samples, a counter going back a little counts a reordered / duplicated sample (dropped), a
// counter going back far (more than kResyncWindow: the module restarted) resynchronises. IMU samples and frames whose
// time stamp is not after the previous one's are dropped and counted (the System needs increasing time stamps).
// Never throws on bad data: every problem is a counter.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/imu/imu_types.h"
#include "linnet/io/sensor_protocol.h"

namespace linnet {

/// A frame as the driver delivers it.
struct DriverFrame {
  std::uint32_t counter = 0;
  Timestamp t = 0;              // by the frame-stamp rule (sensor::frameStamp)
  cv::Mat left, right;          // 8-bit, H x W
  int lost_rows[2] = {0, 0};    // per camera (filled when delivered under the "fill" policy)
  bool complete = true;
};

/// Everything the driver counts (also reported in summary.json by `linnet live`).
struct DriverCounters {
  std::uint64_t packets = 0, bytes = 0;
  std::uint64_t row_packets = 0, imu_packets = 0, frame_packets = 0;
  std::uint64_t bad_packets = 0;         // short, long, unknown type, row out of range, ...
  std::uint64_t duplicate_rows = 0;      // a row already received for the current frame
  std::uint64_t orphan_rows = 0;         // rows with no open frame (before the first frame packet, or its packet lost)
  std::uint64_t lost_rows[2] = {0, 0};   // rows of delivered-or-dropped frames that never arrived, per camera
  std::uint64_t frames_complete = 0, frames_filled = 0, frames_dropped = 0;
  std::uint64_t frames_without_stamp = 0;  // frame packets listing no IMU sample (dropped)
  std::uint64_t lost_frame_packets = 0;    // gaps in the frame counter
  std::uint64_t imu_samples = 0, lost_imu_samples = 0, reordered_imu_samples = 0;
  std::uint64_t stale_imu_samples = 0, stale_frames = 0;  // time stamp not after the previous one's: dropped
  std::uint64_t counter_resyncs = 0;       // IMU / frame counters that jumped far back (module restart)
  std::uint64_t ring_overflows = 0;        // filled in by the driver
  std::uint64_t ring_high_water = 0;
  double receive_cpu_s = 0.0, parse_cpu_s = 0.0;  // thread CPU time, filled in by the driver
};

class FrameAssembler {
 public:
  /// A counter that goes back by more than this is a restart of the module, not a reordered packet.
  static constexpr std::int32_t kResyncWindow = 1024;

  using ImuCallback = std::function<void(const ImuSample&)>;
  using FrameCallback = std::function<void(const DriverFrame&)>;

  FrameAssembler(const SensorOptions& options, ImuCallback on_imu, FrameCallback on_frame);

  /// One datagram.
  void push(const std::uint8_t* data, std::size_t size);
  /// A datagram too long for the receive buffer (only its length is known): counted as bad.
  void pushOversized(std::size_t size);
  /// End of stream: the open frame is completed or handled by the policy.
  void flush();

  const DriverCounters& counters() const { return counters_; }

 private:
  void openFrame(const sensor::FramePacket& packet);
  void closeFrame();
  bool frameFull() const { return rows_received_[0] == options_.height && rows_received_[1] == options_.height; }

  SensorOptions options_;
  ImuCallback on_imu_;
  FrameCallback on_frame_;
  DriverCounters counters_;

  bool open_ = false;
  DriverFrame frame_;
  std::vector<std::uint8_t> have_[2];  // rows received per camera (0/1)
  int rows_received_[2] = {0, 0};
  int last_row_[2] = {-1, -1};  // last row received per camera in the open frame
  bool have_frame_counter_ = false;
  std::uint32_t last_frame_counter_ = 0;
  bool have_imu_counter_ = false;
  std::uint32_t last_imu_counter_ = 0;
  Timestamp last_imu_t_ = 0, last_frame_t_ = 0;
  bool have_imu_t_ = false, have_frame_t_ = false;
};

}  // namespace linnet
