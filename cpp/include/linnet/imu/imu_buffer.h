// A time-ordered buffer of IMU samples with validation on insertion and interpolated extraction of intervals.
#pragma once

#include <cstddef>
#include <deque>
#include <vector>

#include "linnet/core/types.h"
#include "linnet/imu/imu_types.h"

namespace linnet {

struct ImuBufferOptions {
  double max_gap_s =
      0.05;  // s: a larger interval between consecutive samples is an InputError (EuRoC: 0.005 nominal)

  template <class V>
  void visit(V& v) {
    v("max_gap_s", max_gap_s, "largest allowed interval between consecutive IMU samples, s", 1e-4, 10.0);
  }
};

class ImuBuffer {
 public:
  explicit ImuBuffer(const ImuBufferOptions& options = ImuBufferOptions());

  /// Appends a sample. Throws InputError if its time stamp is not strictly after the previous one or if the
  /// gap to the previous one exceeds max_gap_s; the message names both time stamps. The buffer is unchanged
  /// on error.
  void append(const ImuSample& s);

  /// True if [t0, t1] lies within [startTime(), endTime()].
  bool covers(Timestamp t0, Timestamp t1) const;

  /// Samples covering [t0, t1]: a sample exactly at t0 (linearly interpolated between its neighbours unless
  /// one was recorded at t0), every recorded sample strictly inside, and a sample exactly at t1 (likewise).
  /// t0 == t1 gives a single sample. Throws UsageError if t0 > t1 or the interval is not covered.
  std::vector<ImuSample> samplesBetween(Timestamp t0, Timestamp t1) const;

  /// The sample at time t (linear interpolation). Throws UsageError if t is not covered.
  ImuSample sampleAt(Timestamp t) const;

  /// Drops samples no longer needed for intervals starting at or after t (keeps the last sample at or before
  /// t).
  void dropBefore(Timestamp t);

  std::size_t size() const { return samples_.size(); }
  bool empty() const { return samples_.empty(); }
  Timestamp startTime() const { return samples_.empty() ? 0 : samples_.front().t; }
  Timestamp endTime() const { return samples_.empty() ? 0 : samples_.back().t; }
  const ImuBufferOptions& options() const { return options_; }

 private:
  // Index of the last sample with time <= t (requires startTime() <= t).
  std::size_t lastAtOrBefore(Timestamp t) const;

  ImuBufferOptions options_;
  Timestamp max_gap_ns_ = 0;
  std::deque<ImuSample> samples_;
};

/// Linear interpolation between two samples (a.t <= t <= b.t, a.t < b.t).
ImuSample interpolateSample(const ImuSample& a, const ImuSample& b, Timestamp t);

}  // namespace linnet
