#include "linnet/driver/sensor_emulator.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <random>
#include <thread>

#include <opencv2/imgproc.hpp>

#include "linnet/core/error.h"
#include "linnet/io/euroc_dataset.h"

namespace linnet {

namespace {

/// A UDP sender with the drop decision and the pacing.
class Sender {
 public:
  Sender(const EmulatorOptions& o, EmulatorReport* report) : o_(o), report_(report), rng_(o.seed) {
    fd_ = ::socket(AF_INET, SOCK_DGRAM, 0);
    const std::string where = "udp://" + o.host + ":" + std::to_string(o.port);
    if (fd_ < 0) throw InputError(where + ": cannot create a UDP socket: " + std::strerror(errno));
    const int bytes = 16 << 20;
    ::setsockopt(fd_, SOL_SOCKET, SO_SNDBUF, &bytes, sizeof bytes);
    addr_.sin_family = AF_INET;
    addr_.sin_port = htons(static_cast<std::uint16_t>(o.port));
    if (::inet_pton(AF_INET, o.host.c_str(), &addr_.sin_addr) != 1) {
      ::close(fd_);
      throw InputError(where + ": not an IPv4 address");
    }
    wall0_ = std::chrono::steady_clock::now();
  }
  ~Sender() { ::close(fd_); }

  void setDataStart(Timestamp t0) { t0_ = t0; }

  /// Waits until data time t is due (t0 + (t - t0) / rate in wall time).
  void pace(Timestamp t) {
    const double due = toSeconds(t - t0_) / o_.rate;
    const double now = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
    if (due > now + 2e-4) {
      std::this_thread::sleep_for(std::chrono::duration<double>(due - now));
    } else {
      report_->late_s = std::max(report_->late_s, now - due);
    }
  }

  /// Sends (or drops, with probability drop_prob) one packet; true if sent.
  bool send(const std::vector<std::uint8_t>& packet) {
    if (o_.drop_prob > 0.0 && uniform_(rng_) < o_.drop_prob) {
      ++report_->packets_dropped;
      return false;
    }
    for (;;) {
      const ssize_t n = ::sendto(fd_, packet.data(), packet.size(), 0, reinterpret_cast<const sockaddr*>(&addr_),
                                 sizeof addr_);
      if (n >= 0) break;
      if (errno == ENOBUFS || errno == EAGAIN || errno == EINTR) continue;  // the local queue is full: retry
      throw InputError("udp://" + o_.host + ":" + std::to_string(o_.port) + ": send failed: " + std::strerror(errno));
    }
    ++report_->packets_sent;
    report_->bytes_sent += packet.size();
    return true;
  }

  double wallSeconds() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
  }

 private:
  EmulatorOptions o_;
  EmulatorReport* report_;
  int fd_ = -1;
  sockaddr_in addr_{};
  std::mt19937_64 rng_;
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  std::chrono::steady_clock::time_point wall0_;
  Timestamp t0_ = 0;
};

/// The image as the module's W x H (zero padding right / bottom, or cropping).
cv::Mat toModuleSize(const cv::Mat& image, const SensorOptions& s) {
  if (image.cols == s.width && image.rows == s.height) return image;
  cv::Mat out(s.height, s.width, CV_8UC1, cv::Scalar(0));
  const int w = std::min(image.cols, s.width), h = std::min(image.rows, s.height);
  image(cv::Rect(0, 0, w, h)).copyTo(out(cv::Rect(0, 0, w, h)));
  return out;
}

/// The IMU samples the frame packet lists for an image at t (see the header); `stream` is every IMU sample sent, its
/// index being the sample's counter.
sensor::FramePacket framePacket(std::uint32_t counter, Timestamp t, const std::vector<ImuSample>& stream) {
  sensor::FramePacket f;
  f.counter = counter;
  const auto it = std::lower_bound(stream.begin(), stream.end(), t,
                                   [](const ImuSample& s, Timestamp v) { return s.t < v; });
  const std::size_t k = static_cast<std::size_t>(it - stream.begin());
  auto entry = [&](std::size_t i) { return std::make_pair(static_cast<std::uint32_t>(i), stream[i].t); };
  if (k < stream.size() && stream[k].t == t) {
    if (k > 0 && k + 1 < stream.size()) {
      f.imu = {entry(k - 1), entry(k), entry(k + 1)};
    } else {
      f.imu = {entry(k)};  // at an end of the stream: the sample itself (odd count)
    }
  } else if (k > 0 && k < stream.size()) {
    f.imu = {entry(k - 1), entry(k)};
  } else if (!stream.empty()) {
    f.imu = {entry(k == 0 ? 0 : stream.size() - 1)};  // outside the IMU stream: the nearest sample
  }
  return f;
}

}  // namespace

EmulatorReport emulateDataset(const std::string& dataset, const SensorOptions& sensor, const EmulatorOptions& o,
                              const std::function<void(int, int)>& progress,
                              const std::function<bool()>& should_stop) {
  if (!(o.rate > 0.0)) throw UsageError("emulator: rate must be > 0");
  if (!(o.drop_prob >= 0.0 && o.drop_prob < 1.0)) throw UsageError("emulator: drop_prob must be in [0, 1)");
  if (o.loops < 1) throw UsageError("emulator: loops must be >= 1");
  EurocOpenOptions open;
  open.read_calibration = false;
  open.load_ground_truth = false;
  const EurocDataset ds = EurocDataset::open(dataset, open);
  const auto& frames = ds.frames();
  const auto& imu = ds.imu();
  if (frames.empty() || imu.empty()) throw InputError(dataset, 0, "no images or no IMU samples to stream");

  // The images streamed: up to duration_s after the first.
  std::size_t n_frames = frames.size();
  if (o.duration_s >= 0.0)
    while (n_frames > 1 && toSeconds(frames[n_frames - 1].t - frames.front().t) > o.duration_s) --n_frames;
  const Timestamp period = n_frames > 1 ? (frames[n_frames - 1].t - frames.front().t) / static_cast<Timestamp>(n_frames - 1)
                                        : 50'000'000;
  const Timestamp loop_span = frames[n_frames - 1].t - frames.front().t + period;  // data time of one loop

  // Every IMU sample to send, all loops, strictly increasing (a loop's samples before the previous loop's last one
  // are left out); a sample's index is its counter.
  const Timestamp t_start = frames.front().t - fromSeconds(o.imu_lead_s);
  std::vector<ImuSample> stream;
  for (int loop = 0; loop < o.loops; ++loop) {
    const Timestamp shift = loop * loop_span;
    const Timestamp t_end = frames[n_frames - 1].t + shift + period;
    for (const ImuSample& sample : imu) {
      ImuSample s = sample;
      s.t += shift;
      if (s.t < t_start || s.t > t_end || (!stream.empty() && s.t <= stream.back().t)) continue;
      stream.push_back(s);
    }
  }

  if (stream.empty())
    throw InputError(dataset, 0,
                     "no IMU sample within the images' time span (imu0/data.csv and cam0/data.csv must be in ns on "
                     "the same clock)");

  EmulatorReport report;
  Sender sender(o, &report);
  sender.setDataStart(t_start);
  const int total = static_cast<int>(n_frames) * o.loops;
  std::uint32_t frame_counter = 0;
  std::size_t next_imu = 0;
  auto stopRequested = [&] { return should_stop && should_stop(); };
  auto sendImuUntil = [&](Timestamp t) {  // every IMU sample up to data time t, paced
    for (; next_imu < stream.size() && stream[next_imu].t <= t; ++next_imu) {
      const auto counter = static_cast<std::uint32_t>(next_imu);
      sender.pace(stream[next_imu].t);
      if (sender.send(sensor::encodeImu(sensor::quantise(stream[next_imu], counter, sensor)))) {
        ++report.imu_samples;
      } else {
        ++report.imu_dropped;
        report.dropped.push_back({"imu", 0, -1, -1, counter});
      }
    }
  };

  for (int loop = 0; loop < o.loops && !stopRequested(); ++loop) {
    const Timestamp shift = loop * loop_span;
    for (std::size_t i = 0; i < n_frames && !stopRequested(); ++i) {
      const Timestamp t = frames[i].t + shift;
      sendImuUntil(t);
      const cv::Mat left = toModuleSize(EurocDataset::loadImage(frames[i].left_path), sensor);
      const cv::Mat right =
          frames[i].right_path.empty() ? left : toModuleSize(EurocDataset::loadImage(frames[i].right_path), sensor);
      sender.pace(t);
      const bool header_sent = sender.send(sensor::encodeFrame(framePacket(frame_counter, t, stream)));
      if (!header_sent) {
        ++report.frames_dropped;
        report.dropped.push_back({"frame", frame_counter, -1, -1, 0});
      }
      bool any_row_dropped = false;
      const int h = sensor.height;
      const Timestamp spread = static_cast<Timestamp>(o.row_spread * static_cast<double>(period));
      for (int r = 0; r < h; ++r) {
        const Timestamp t_row = t + spread * r / h;
        sendImuUntil(t_row);
        sender.pace(t_row);
        for (int c = 0; c < 2; ++c) {
          const cv::Mat& image = c == 0 ? left : right;
          if (sender.send(sensor::encodeRow(c, r, image.ptr(r), sensor.width))) {
            ++report.rows_sent[c];
            if (!header_sent) ++report.rows_of_headless_frames[c];
          } else {
            if (header_sent) {
              ++report.rows_dropped[c];
              any_row_dropped = true;
            }
            report.dropped.push_back({"row", frame_counter, c, r, 0});
          }
        }
      }
      if (header_sent && any_row_dropped) ++report.frames_with_dropped_rows;
      ++frame_counter;
      ++report.frames;
      if (progress) progress(static_cast<int>(report.frames), total);
    }
  }
  if (!stopRequested()) sendImuUntil(stream.back().t);
  report.wall_s = sender.wallSeconds();
  report.data_s = toSeconds(stream.back().t - t_start);
  return report;
}

}  // namespace linnet
