// The driver's parse side: frames rebuilt by row number, lost / duplicated / orphan rows, the incomplete-frame
// policy, IMU counters; and the ring buffer between the threads.
#include <gtest/gtest.h>

#include <atomic>
#include <random>
#include <set>
#include <thread>

#include "driver/driver_test_stream.h"
#include "linnet/driver/frame_assembler.h"
#include "linnet/driver/packet_ring.h"

namespace linnet {
namespace {

SensorOptions small(const std::string& incomplete = "drop") {
  SensorOptions o;
  o.width = 16;
  o.height = 20;
  o.incomplete = incomplete;
  o.max_lost_rows_fraction = 0.1;  // 2 rows
  return o;
}

struct Collected {
  std::vector<DriverFrame> frames;
  std::vector<ImuSample> imu;
};

FrameAssembler assembler(const SensorOptions& o, Collected* out) {
  return FrameAssembler(
      o, [out](const ImuSample& s) { out->imu.push_back(s); },
      [out](const DriverFrame& f) {
        DriverFrame copy = f;
        copy.left = f.left.clone();
        copy.right = f.right.clone();
        out->frames.push_back(copy);
      });
}

void feed(FrameAssembler& a, const std::vector<std::vector<std::uint8_t>>& packets) {
  for (const auto& p : packets) a.push(p.data(), p.size());
  a.flush();
}

bool pixelsMatch(const DriverFrame& f, int frame) {
  for (int c = 0; c < 2; ++c) {
    const cv::Mat& im = c == 0 ? f.left : f.right;
    for (int r = 0; r < im.rows; ++r)
      for (int x = 0; x < im.cols; ++x)
        if (im.at<std::uint8_t>(r, x) != driver_test::pixel(frame, c, r, x)) return false;
  }
  return true;
}

TEST(FrameAssembler, CompleteStreamGivesEveryFrameAndSample) {
  const SensorOptions o = small();
  Collected got;
  FrameAssembler a = assembler(o, &got);
  feed(a, driver_test::stream(o, 5));
  ASSERT_EQ(got.frames.size(), 5u);
  for (int f = 0; f < 5; ++f) {
    EXPECT_EQ(got.frames[f].t, 1'000'000'000 + f * 50'000'000LL);
    EXPECT_TRUE(got.frames[f].complete);
    EXPECT_TRUE(pixelsMatch(got.frames[f], f));
  }
  EXPECT_EQ(got.imu.size(), 50u);
  for (std::size_t i = 1; i < got.imu.size(); ++i) EXPECT_GT(got.imu[i].t, got.imu[i - 1].t);
  const DriverCounters& c = a.counters();
  EXPECT_EQ(c.frames_complete, 5u);
  EXPECT_EQ(c.lost_rows[0] + c.lost_rows[1] + c.bad_packets + c.duplicate_rows + c.orphan_rows, 0u);
}

TEST(FrameAssembler, LostRowsAreCountedExactlyAndHandledByThePolicy) {
  for (const std::string policy : {"drop", "fill"}) {
    const SensorOptions o = small(policy);
    auto packets = driver_test::stream(o, 3);
    // Frame 0 (packets 10..): lose cam0 row 5 and cam1 row 6 (2 rows: within "fill"'s limit); frame 1: lose 6 rows.
    const std::size_t f0 = 11, f1 = f0 + 2 * 20 + 11;
    std::set<std::size_t> lose = {f0 + 2 * 5 + 0, f0 + 2 * 6 + 1};
    for (int r = 0; r < 3; ++r) lose.insert(f1 + 2 * r + 0), lose.insert(f1 + 2 * r + 1);
    std::vector<std::vector<std::uint8_t>> kept;
    for (std::size_t i = 0; i < packets.size(); ++i)
      if (!lose.count(i)) kept.push_back(packets[i]);
    Collected got;
    FrameAssembler a = assembler(o, &got);
    feed(a, kept);
    const DriverCounters& c = a.counters();
    EXPECT_EQ(c.lost_rows[0], 4u) << policy;
    EXPECT_EQ(c.lost_rows[1], 4u) << policy;
    EXPECT_EQ(c.frames_complete, 1u);
    if (policy == "drop") {
      EXPECT_EQ(c.frames_dropped, 2u);
      ASSERT_EQ(got.frames.size(), 1u);
      EXPECT_EQ(got.frames[0].counter, 2u);
    } else {
      EXPECT_EQ(c.frames_filled, 1u);   // frame 0: 1 row per camera lost
      EXPECT_EQ(c.frames_dropped, 1u);  // frame 1: 3 rows per camera, over the limit
      ASSERT_EQ(got.frames.size(), 2u);
      const DriverFrame& f = got.frames[0];
      EXPECT_FALSE(f.complete);
      EXPECT_EQ(f.lost_rows[0], 1);
      // The lost row is a copy of the row above it.
      EXPECT_EQ(cv::norm(f.left.row(5), f.left.row(4), cv::NORM_INF), 0.0);
      EXPECT_EQ(cv::norm(f.right.row(6), f.right.row(5), cv::NORM_INF), 0.0);
    }
  }
}

TEST(FrameAssembler, DuplicatesReorderedImuAndALostFramePacket) {
  const SensorOptions o = small();
  auto packets = driver_test::stream(o, 3);
  std::vector<std::vector<std::uint8_t>> mangled;
  for (std::size_t i = 0; i < packets.size(); ++i) {
    if (i == 51 + 10) continue;  // frame 1's frame packet (after its 10 IMU packets)
    mangled.push_back(packets[i]);
    if (i == 15) mangled.push_back(packets[i]);  // a duplicated row of frame 0
    if (i == 3) mangled.push_back(packets[1]);   // an IMU sample again, late
  }
  Collected got;
  FrameAssembler a = assembler(o, &got);
  feed(a, mangled);
  const DriverCounters& c = a.counters();
  EXPECT_EQ(c.duplicate_rows, 1u);
  EXPECT_EQ(c.reordered_imu_samples, 1u);
  EXPECT_EQ(c.lost_frame_packets, 1u);
  EXPECT_EQ(c.orphan_rows, 40u);  // frame 1's rows: no frame open (frame 0 was complete)
  ASSERT_EQ(got.frames.size(), 2u);
  EXPECT_TRUE(pixelsMatch(got.frames[0], 0));
  EXPECT_TRUE(pixelsMatch(got.frames[1], 2));
  EXPECT_EQ(got.imu.size(), 30u);
}

TEST(FrameAssembler, ALostFramePacketAfterAnIncompleteFrameDoesNotMixFrames) {
  const SensorOptions o = small();
  auto packets = driver_test::stream(o, 3);
  std::vector<std::vector<std::uint8_t>> kept;
  for (std::size_t i = 0; i < packets.size(); ++i)
    if (i != 11 + 39 && i != 51 + 10) kept.push_back(packets[i]);  // frame 0's last cam1 row; frame 1's packet
  Collected got;
  FrameAssembler a = assembler(o, &got);
  feed(a, kept);
  const DriverCounters& c = a.counters();
  EXPECT_EQ(c.lost_rows[1], 1u);   // frame 0, closed when frame 1's rows wrapped to row 0
  EXPECT_EQ(c.lost_rows[0], 0u);
  EXPECT_EQ(c.frames_dropped, 1u);
  EXPECT_EQ(c.orphan_rows, 40u);
  ASSERT_EQ(got.frames.size(), 1u);
  EXPECT_TRUE(pixelsMatch(got.frames[0], 2));
}

TEST(FrameAssembler, StaleStampsAndAModuleRestartAreCountedNotDelivered) {
  const SensorOptions o = small();
  auto first = driver_test::stream(o, 2);
  auto restarted = driver_test::stream(o, 2);  // counters and clock start again (a power cycle)
  std::vector<std::vector<std::uint8_t>> all = first;
  all.insert(all.end(), restarted.begin(), restarted.end());
  Collected got;
  FrameAssembler a = assembler(o, &got);
  feed(a, all);
  const DriverCounters& c = a.counters();
  // The restart is a resync, not 2^32 lost or reordered samples; its samples and frames are stale (not after the
  // last delivered stamps), so the System never sees time going back.
  EXPECT_EQ(c.counter_resyncs, 0u);  // counters back by 20 / 2: within the window, counted as reordered
  EXPECT_EQ(got.frames.size(), 2u);
  EXPECT_EQ(got.imu.size(), 20u);
  for (std::size_t i = 1; i < got.imu.size(); ++i) EXPECT_GT(got.imu[i].t, got.imu[i - 1].t);
  EXPECT_EQ(c.stale_frames, 2u);

  // A far jump back of the counter (beyond the resync window) with later stamps is followed.
  SensorOptions o2 = small();
  Collected got2;
  FrameAssembler b = assembler(o2, &got2);
  ImuSample s;
  s.t = 100;
  const auto p1 = sensor::encodeImu(sensor::quantise(s, 50000, o2));
  s.t = 200;
  const auto p2 = sensor::encodeImu(sensor::quantise(s, 3, o2));
  s.t = 300;
  const auto p3 = sensor::encodeImu(sensor::quantise(s, 4, o2));
  for (const auto* p : {&p1, &p2, &p3}) b.push(p->data(), p->size());
  EXPECT_EQ(b.counters().counter_resyncs, 1u);
  EXPECT_EQ(got2.imu.size(), 3u);
  EXPECT_EQ(b.counters().lost_imu_samples, 0u);
}

TEST(PacketRing, FastProducerDropPolicyCountsAndNeverCorrupts) {
  for (const bool block : {false, true}) {
    PacketRing ring(64, 16, block);
    constexpr std::uint32_t kPackets = 200000;
    std::atomic<std::uint64_t> written{0};
    std::thread producer([&] {
      for (std::uint32_t i = 0; i < kPackets; ++i) {
        std::uint8_t* slot = ring.beginWrite();
        if (slot == nullptr) {
          ring.noteOverflow();
          continue;
        }
        for (int b = 0; b < 4; ++b) slot[b] = static_cast<std::uint8_t>(i >> (8 * b));
        slot[4] = static_cast<std::uint8_t>(i * 7);
        ring.commitWrite(5);
        ++written;
      }
      ring.close();
    });
    std::uint64_t read = 0;
    std::int64_t last = -1;
    bool ordered = true, intact = true;
    for (;;) {
      std::size_t size = 0;
      const std::uint8_t* p = ring.beginRead(&size, 100);
      if (p == nullptr) {
        if (ring.drained()) break;
        continue;
      }
      const std::uint32_t i = p[0] | p[1] << 8 | p[2] << 16 | static_cast<std::uint32_t>(p[3]) << 24;
      intact = intact && size == 5 && p[4] == static_cast<std::uint8_t>(i * 7);
      ordered = ordered && static_cast<std::int64_t>(i) > last;
      last = i;
      ++read;
      if (read % 1000 == 0) std::this_thread::sleep_for(std::chrono::microseconds(200));  // a slow consumer
      ring.endRead();
    }
    producer.join();
    EXPECT_TRUE(intact) << block;
    EXPECT_TRUE(ordered) << block;
    EXPECT_EQ(read, written.load());
    EXPECT_EQ(read + ring.overflows(), kPackets);
    if (block) {
      EXPECT_EQ(ring.overflows(), 0u);
    } else {
      EXPECT_GT(ring.overflows(), 0u);
    }
    EXPECT_LE(ring.highWater(), 64u);
  }
}

}  // namespace
}  // namespace linnet
