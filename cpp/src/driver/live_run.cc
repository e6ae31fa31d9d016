#include "linnet/driver/live_run.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <mutex>
#include <thread>

#include <opencv2/imgcodecs.hpp>

#include "linnet/core/error.h"

namespace linnet {

namespace {

namespace fs = std::filesystem;

/// Writes the stream as a EuRoC folder: mav0/cam0|cam1/data/<t>.png + data.csv, mav0/imu0/data.csv (full precision).
class Recorder {
 public:
  explicit Recorder(const std::string& dir) {
    const fs::path mav0 = fs::path(dir) / "mav0";
    std::error_code ec;
    for (const char* cam : {"cam0", "cam1"}) {
      fs::create_directories(mav0 / cam / "data", ec);
      if (ec) throw InputError(dir, 0, "cannot create the recording folder: " + ec.message());
    }
    fs::create_directories(mav0 / "imu0", ec);
    mav0_ = mav0;
    imu_ = open(mav0 / "imu0" / "data.csv",
                "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
                "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n");
    cams_[0] = open(mav0 / "cam0" / "data.csv", "#timestamp [ns],filename\n");
    cams_[1] = open(mav0 / "cam1" / "data.csv", "#timestamp [ns],filename\n");
  }
  ~Recorder() {
    for (std::FILE* f : {imu_, cams_[0], cams_[1]})
      if (f != nullptr) std::fclose(f);
  }
  void imu(const ImuSample& s) {
    std::fprintf(imu_, "%lld,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", static_cast<long long>(s.t), s.gyr[0], s.gyr[1],
                 s.gyr[2], s.acc[0], s.acc[1], s.acc[2]);
    ++imu_count;
  }
  void frame(const DriverFrame& f) {
    const std::string name = std::to_string(f.t) + ".png";
    for (int c = 0; c < 2; ++c) {
      const fs::path path = mav0_ / (c == 0 ? "cam0" : "cam1") / "data" / name;
      if (!cv::imwrite(path.string(), c == 0 ? f.left : f.right))
        throw InputError(path.string(), 0, "cannot write the recorded image");
      std::fprintf(cams_[c], "%lld,%s\n", static_cast<long long>(f.t), name.c_str());
    }
    ++frame_count;
  }
  int imu_count = 0, frame_count = 0;

 private:
  static std::FILE* open(const fs::path& path, const char* header) {
    std::FILE* f = std::fopen(path.string().c_str(), "w");
    if (f == nullptr) throw InputError(path.string(), 0, "cannot write");
    std::fputs(header, f);
    return f;
  }
  fs::path mav0_;
  std::FILE* imu_ = nullptr;
  std::FILE* cams_[2] = {nullptr, nullptr};
};

}  // namespace

LiveResult runLive(const Config& config, const LiveOptions& options, const std::function<void(int)>& on_ready,
                   const std::function<bool()>& should_stop, const std::function<void(const LiveStatus&)>& status) {
  Config cfg = config;
  cfg.pipeline.blocking = false;  // live: frames the system cannot take in time are dropped
  if (options.run_system && (cfg.cam0.width != cfg.sensor.width || cfg.cam0.height != cfg.sensor.height))
    throw ConfigError("config key 'sensor.width/height' (" + std::to_string(cfg.sensor.width) + "x" +
                      std::to_string(cfg.sensor.height) + ") differs from the camera calibration's image size (" +
                      std::to_string(cfg.cam0.width) + "x" + std::to_string(cfg.cam0.height) + ")");
  // Declared before the run whose callback uses them: they outlive it on every path.
  std::atomic<int> frames{0}, dropped{0}, processed{0};
  std::atomic<int> tracking{-1};
  std::unique_ptr<StreamRun> run;
  if (options.run_system) run = std::make_unique<StreamRun>(cfg);
  std::unique_ptr<Recorder> recorder;
  if (!options.record_dir.empty()) recorder = std::make_unique<Recorder>(options.record_dir);
  if (run)
    run->setCallback([&](const FrameResult& r) {
      ++processed;
      tracking = static_cast<int>(r.estimate.status);
    });
  UdpDriver driver(
      cfg.sensor, options.host, options.port,
      [&](const ImuSample& s) {
        if (recorder) recorder->imu(s);
        if (run) run->addImu(s.t, s.acc, s.gyr);
      },
      [&](const DriverFrame& f) {
        ++frames;
        if (recorder) recorder->frame(f);
        if (run && !run->addFrame(f.t, f.left, f.right)) ++dropped;
      });
  if (on_ready) on_ready(driver.port());

  LiveResult result;
  const auto t0 = std::chrono::steady_clock::now();
  auto last_status = t0;
  std::chrono::steady_clock::time_point first_packet{};
  for (;;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    driver.rethrowError();
    const auto now = std::chrono::steady_clock::now();
    if (driver.receivedAny() && first_packet == std::chrono::steady_clock::time_point{}) first_packet = now;
    if (should_stop && should_stop()) {
      result.end_reason = "stopped";
      break;
    }
    if (options.duration_s >= 0.0 && first_packet != std::chrono::steady_clock::time_point{} &&
        std::chrono::duration<double>(now - first_packet).count() >= options.duration_s) {
      result.end_reason = "duration";
      break;
    }
    if (driver.receivedAny() && driver.idleSeconds() >= cfg.sensor.idle_timeout_s) {
      result.end_reason = "idle";
      break;
    }
    if (status && now - last_status >= std::chrono::milliseconds(500)) {
      last_status = now;
      const DriverCounters c = driver.counters();
      LiveStatus s;
      s.elapsed_s = std::chrono::duration<double>(now - t0).count();
      s.frames = frames.load();
      s.processed = processed.load();
      s.dropped = dropped.load();
      s.lost_rows = c.lost_rows[0] + c.lost_rows[1];
      s.imu_samples = c.imu_samples;
      const int tr = tracking.load();
      s.tracking = tr < 0 ? "waiting" : toString(static_cast<TrackingStatus>(tr));
      status(s);
    }
  }
  driver.stop();
  driver.rethrowError();
  result.counters = driver.counters();
  if (recorder) {
    result.recorded_frames = recorder->frame_count;
    result.recorded_imu = recorder->imu_count;
  }
  if (run) {
    if (run->frames() == 0) {
      result.summary.warnings.push_back("no frame was received");
    } else {
      result.summary = run->finish();
    }
  }
  return result;
}

}  // namespace linnet
