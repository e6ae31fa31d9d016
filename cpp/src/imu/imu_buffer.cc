// ImuBuffer: validated insertion, interpolated interval extraction.
#include "linnet/imu/imu_buffer.h"

#include <algorithm>
#include <sstream>
#include <string>

#include "linnet/core/error.h"
#include "linnet/core/options.h"

namespace linnet {

ImuBuffer::ImuBuffer(const ImuBufferOptions& options) : options_(options) {
  validateOptions(options_, "imu_buffer");
  max_gap_ns_ = fromSeconds(options_.max_gap_s);
}

void ImuBuffer::append(const ImuSample& s) {
  if (!samples_.empty()) {
    const Timestamp prev = samples_.back().t;
    if (s.t <= prev) {
      throw InputError("IMU time stamps not strictly increasing: sample at t=" + std::to_string(s.t) +
                       " ns follows t=" + std::to_string(prev) + " ns");
    }
    if (s.t - prev > max_gap_ns_) {
      std::ostringstream os;
      os << "IMU gap of " << toSeconds(s.t - prev) << " s between t=" << prev << " ns and t=" << s.t
         << " ns exceeds imu_buffer.max_gap_s = " << options_.max_gap_s << " s";
      throw InputError(os.str());
    }
  }
  samples_.push_back(s);
}

bool ImuBuffer::covers(Timestamp t0, Timestamp t1) const {
  return !samples_.empty() && t0 <= t1 && samples_.front().t <= t0 && t1 <= samples_.back().t;
}

std::size_t ImuBuffer::lastAtOrBefore(Timestamp t) const {
  const auto it = std::upper_bound(samples_.begin(), samples_.end(), t,
                                   [](Timestamp value, const ImuSample& s) { return value < s.t; });
  return static_cast<std::size_t>(it - samples_.begin()) - 1;
}

ImuSample interpolateSample(const ImuSample& a, const ImuSample& b, Timestamp t) {
  if (t == a.t) return a;
  if (t == b.t) return b;
  const double u = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  ImuSample s;
  s.t = t;
  s.acc = (1.0 - u) * a.acc + u * b.acc;
  s.gyr = (1.0 - u) * a.gyr + u * b.gyr;
  return s;
}

ImuSample ImuBuffer::sampleAt(Timestamp t) const {
  if (!covers(t, t))
    throw UsageError("ImuBuffer::sampleAt: t=" + std::to_string(t) +
                     " ns is outside the buffered IMU data [" + std::to_string(startTime()) + ", " +
                     std::to_string(endTime()) + "] ns");
  const std::size_t i = lastAtOrBefore(t);
  if (samples_[i].t == t || i + 1 == samples_.size()) return samples_[i];
  return interpolateSample(samples_[i], samples_[i + 1], t);
}

std::vector<ImuSample> ImuBuffer::samplesBetween(Timestamp t0, Timestamp t1) const {
  if (t0 > t1)
    throw UsageError("ImuBuffer::samplesBetween: t0=" + std::to_string(t0) +
                     " ns is after t1=" + std::to_string(t1) + " ns");
  if (!covers(t0, t1))
    throw UsageError("ImuBuffer::samplesBetween: [" + std::to_string(t0) + ", " + std::to_string(t1) +
                     "] ns is not covered by the buffered IMU data [" + std::to_string(startTime()) + ", " +
                     std::to_string(endTime()) + "] ns");
  std::vector<ImuSample> out;
  out.push_back(sampleAt(t0));
  if (t1 == t0) return out;
  for (std::size_t i = lastAtOrBefore(t0) + 1; i < samples_.size() && samples_[i].t < t1; ++i)
    out.push_back(samples_[i]);
  out.push_back(sampleAt(t1));
  return out;
}

void ImuBuffer::dropBefore(Timestamp t) {
  if (samples_.empty() || t <= samples_.front().t) return;
  const std::size_t keep_from = lastAtOrBefore(t);
  samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(keep_from));
}

}  // namespace linnet
