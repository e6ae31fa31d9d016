#include "linnet/driver/frame_assembler.h"

#include <cstring>

namespace linnet {

FrameAssembler::FrameAssembler(const SensorOptions& options, ImuCallback on_imu, FrameCallback on_frame)
    : options_(options), on_imu_(std::move(on_imu)), on_frame_(std::move(on_frame)) {
  for (auto& h : have_) h.assign(static_cast<std::size_t>(options_.height), 0);
}

void FrameAssembler::push(const std::uint8_t* data, std::size_t size) {
  ++counters_.packets;
  counters_.bytes += size;
  const sensor::DecodedPacket p = sensor::decode(data, size, options_);
  switch (p.kind) {
    case sensor::PacketKind::kBad:
      ++counters_.bad_packets;
      return;
    case sensor::PacketKind::kImu: {
      ++counters_.imu_packets;
      if (have_imu_counter_) {
        const std::uint32_t expected = last_imu_counter_ + 1;
        if (p.imu.counter != expected) {
          // Counter differences as signed 32-bit: ahead = lost samples, a little behind = reordered / duplicated,
          // far behind = the module restarted (resynchronise).
          const auto diff = static_cast<std::int32_t>(p.imu.counter - expected);
          if (diff < -kResyncWindow) {
            ++counters_.counter_resyncs;
          } else if (diff < 0) {
            ++counters_.reordered_imu_samples;
            return;
          } else {
            counters_.lost_imu_samples += static_cast<std::uint64_t>(diff);
          }
        }
      }
      have_imu_counter_ = true;
      last_imu_counter_ = p.imu.counter;
      if (have_imu_t_ && p.imu.t <= last_imu_t_) {
        ++counters_.stale_imu_samples;
        return;
      }
      have_imu_t_ = true;
      last_imu_t_ = p.imu.t;
      ++counters_.imu_samples;
      if (on_imu_) on_imu_(sensor::dequantise(p.imu, options_));
      return;
    }
    case sensor::PacketKind::kFrame:
      ++counters_.frame_packets;
      if (open_) closeFrame();
      if (have_frame_counter_ && p.frame.counter != last_frame_counter_ + 1) {
        const auto diff = static_cast<std::int32_t>(p.frame.counter - (last_frame_counter_ + 1));
        if (diff > 0) counters_.lost_frame_packets += static_cast<std::uint64_t>(diff);
        if (diff < -kResyncWindow) ++counters_.counter_resyncs;
      }
      have_frame_counter_ = true;
      last_frame_counter_ = p.frame.counter;
      openFrame(p.frame);
      return;
    case sensor::PacketKind::kRow: {
      ++counters_.row_packets;
      if (!open_) {
        ++counters_.orphan_rows;
        return;
      }
      auto& have = have_[p.camera];
      if (p.row < last_row_[p.camera]) {  // wrapped: a new exposure whose frame packet was lost
        closeFrame();
        ++counters_.orphan_rows;
        return;
      }
      if (have[static_cast<std::size_t>(p.row)]) {
        ++counters_.duplicate_rows;
        return;
      }
      last_row_[p.camera] = p.row;
      have[static_cast<std::size_t>(p.row)] = 1;
      ++rows_received_[p.camera];
      cv::Mat& image = p.camera == 0 ? frame_.left : frame_.right;
      std::memcpy(image.ptr(p.row), p.pixels, static_cast<std::size_t>(options_.width));
      if (frameFull()) closeFrame();
      return;
    }
  }
}

void FrameAssembler::pushOversized(std::size_t size) {
  ++counters_.packets;
  counters_.bytes += size;
  ++counters_.bad_packets;
}

void FrameAssembler::openFrame(const sensor::FramePacket& packet) {
  const auto t = sensor::frameStamp(packet);
  open_ = true;
  frame_ = DriverFrame{};
  frame_.counter = packet.counter;
  frame_.t = t.value_or(-1);
  frame_.left = cv::Mat(options_.height, options_.width, CV_8UC1);
  frame_.right = cv::Mat(options_.height, options_.width, CV_8UC1);
  for (int c = 0; c < 2; ++c) {
    std::fill(have_[c].begin(), have_[c].end(), 0);
    rows_received_[c] = 0;
    last_row_[c] = -1;
  }
}

void FrameAssembler::closeFrame() {
  open_ = false;
  const int h = options_.height;
  for (int c = 0; c < 2; ++c) {
    frame_.lost_rows[c] = h - rows_received_[c];
    counters_.lost_rows[c] += static_cast<std::uint64_t>(frame_.lost_rows[c]);
  }
  if (frame_.t < 0) {
    ++counters_.frames_without_stamp;
    ++counters_.frames_dropped;
    return;
  }
  if (have_frame_t_ && frame_.t <= last_frame_t_) {  // not after the previous frame: the System could not take it
    ++counters_.stale_frames;
    ++counters_.frames_dropped;
    return;
  }
  have_frame_t_ = true;
  last_frame_t_ = frame_.t;
  if (frame_.lost_rows[0] == 0 && frame_.lost_rows[1] == 0) {
    ++counters_.frames_complete;
    if (on_frame_) on_frame_(frame_);
    return;
  }
  frame_.complete = false;
  const int limit = static_cast<int>(options_.max_lost_rows_fraction * h);
  const bool fill = options_.incomplete == "fill" && frame_.lost_rows[0] <= limit && frame_.lost_rows[1] <= limit &&
                    rows_received_[0] > 0 && rows_received_[1] > 0;
  if (!fill) {
    ++counters_.frames_dropped;
    return;
  }
  // Each lost row copies the nearest received row above it (below it for the top rows).
  for (int c = 0; c < 2; ++c) {
    cv::Mat& image = c == 0 ? frame_.left : frame_.right;
    int source = -1;
    for (int r = 0; r < h && source < 0; ++r)
      if (have_[c][static_cast<std::size_t>(r)]) source = r;
    for (int r = 0; r < h; ++r) {
      if (have_[c][static_cast<std::size_t>(r)]) {
        source = r;
      } else {
        std::memcpy(image.ptr(r), image.ptr(source), static_cast<std::size_t>(options_.width));
      }
    }
  }
  ++counters_.frames_filled;
  if (on_frame_) on_frame_(frame_);
}

void FrameAssembler::flush() {
  if (open_) closeFrame();
}

}  // namespace linnet
