// ImuBuffer: validation errors, interpolated interval extraction, trimming.
#include <functional>
#include <string>

#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/imu/imu_buffer.h"

namespace linnet {
namespace {

constexpr Timestamp kMs = 1'000'000;

ImuSample linearSample(Timestamp t) {
  // Readings linear in time, so interpolation is exact.
  const double s = toSeconds(t);
  return {t, Vec3(1.0 + s, 2.0 - 3.0 * s, 9.81), Vec3(0.1 * s, -0.2, 0.3 + s)};
}

ImuBuffer filled(Timestamp t0, Timestamp t1, Timestamp dt) {
  ImuBuffer b;
  for (Timestamp t = t0; t <= t1; t += dt) b.append(linearSample(t));
  return b;
}

std::string messageOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(ImuBuffer, RejectsNonMonotonicTimeStampsNamingThem) {
  ImuBuffer b;
  b.append(linearSample(100 * kMs));
  b.append(linearSample(105 * kMs));
  EXPECT_THROW(b.append(linearSample(105 * kMs)), InputError);
  const std::string msg = messageOf([&] { b.append(linearSample(103 * kMs)); });
  EXPECT_NE(msg.find("103000000"), std::string::npos) << msg;
  EXPECT_NE(msg.find("105000000"), std::string::npos) << msg;
  EXPECT_EQ(b.size(), 2u);  // unchanged on error
  EXPECT_EQ(b.endTime(), 105 * kMs);
}

TEST(ImuBuffer, RejectsGapsLargerThanTheOption) {
  ImuBufferOptions opt;
  opt.max_gap_s = 0.02;
  ImuBuffer b(opt);
  b.append(linearSample(0));
  b.append(linearSample(20 * kMs));  // exactly the limit: fine
  const std::string msg = messageOf([&] { b.append(linearSample(41 * kMs)); });
  EXPECT_NE(msg.find("41000000"), std::string::npos) << msg;
  EXPECT_NE(msg.find("20000000"), std::string::npos) << msg;
  EXPECT_NE(msg.find("max_gap_s"), std::string::npos) << msg;
  EXPECT_THROW(b.append(linearSample(41 * kMs)), InputError);
  EXPECT_EQ(b.size(), 2u);
}

TEST(ImuBuffer, BadOptionIsAConfigError) {
  ImuBufferOptions opt;
  opt.max_gap_s = -1.0;
  EXPECT_THROW(ImuBuffer{opt}, ConfigError);
}

TEST(ImuBuffer, SamplesBetweenInterpolatesBothEnds) {
  const ImuBuffer b = filled(0, 100 * kMs, 5 * kMs);
  const Timestamp t0 = 12 * kMs + 345, t1 = 57 * kMs + 1;
  const auto s = b.samplesBetween(t0, t1);
  ASSERT_GE(s.size(), 2u);
  EXPECT_EQ(s.front().t, t0);
  EXPECT_EQ(s.back().t, t1);
  // 15, 20, ..., 55 ms inside.
  EXPECT_EQ(s.size(), 2u + 9u);
  for (size_t i = 1; i < s.size(); ++i) EXPECT_GT(s[i].t, s[i - 1].t);
  for (const ImuSample& x : s) {
    const ImuSample e = linearSample(x.t);
    EXPECT_LT((x.acc - e.acc).norm(), 1e-12);
    EXPECT_LT((x.gyr - e.gyr).norm(), 1e-12);
  }
}

TEST(ImuBuffer, SamplesBetweenOnRecordedStampsAndDegenerateInterval) {
  const ImuBuffer b = filled(0, 100 * kMs, 5 * kMs);
  const auto s = b.samplesBetween(10 * kMs, 30 * kMs);
  ASSERT_EQ(s.size(), 5u);  // 10, 15, 20, 25, 30: no duplicates
  EXPECT_EQ(s.front().t, 10 * kMs);
  EXPECT_EQ(s.back().t, 30 * kMs);
  const auto whole = b.samplesBetween(0, 100 * kMs);
  EXPECT_EQ(whole.size(), b.size());
  const auto one = b.samplesBetween(42 * kMs, 42 * kMs);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one[0].t, 42 * kMs);
  const auto close = b.samplesBetween(11 * kMs, 12 * kMs);  // no recorded sample inside
  ASSERT_EQ(close.size(), 2u);
}

TEST(ImuBuffer, UncoveredIntervalIsAUsageError) {
  const ImuBuffer b = filled(10 * kMs, 100 * kMs, 5 * kMs);
  EXPECT_FALSE(b.covers(5 * kMs, 50 * kMs));
  EXPECT_FALSE(b.covers(50 * kMs, 101 * kMs));
  EXPECT_TRUE(b.covers(10 * kMs, 100 * kMs));
  EXPECT_THROW(b.samplesBetween(5 * kMs, 50 * kMs), UsageError);
  EXPECT_THROW(b.samplesBetween(50 * kMs, 101 * kMs), UsageError);
  EXPECT_THROW(b.samplesBetween(60 * kMs, 50 * kMs), UsageError);
  EXPECT_THROW(ImuBuffer().samplesBetween(0, 1), UsageError);
}

TEST(ImuBuffer, DropBeforeKeepsWhatLaterIntervalsNeed) {
  ImuBuffer b = filled(0, 100 * kMs, 5 * kMs);
  b.dropBefore(42 * kMs);
  EXPECT_EQ(b.startTime(), 40 * kMs);  // the last sample at or before 42 ms stays for interpolation
  const auto s = b.samplesBetween(42 * kMs, 50 * kMs);
  EXPECT_EQ(s.front().t, 42 * kMs);
  EXPECT_LT((s.front().acc - linearSample(42 * kMs).acc).norm(), 1e-12);
  b.dropBefore(45 * kMs);
  EXPECT_EQ(b.startTime(), 45 * kMs);
  b.dropBefore(0);
  EXPECT_EQ(b.startTime(), 45 * kMs);
}

}  // namespace
}  // namespace linnet
