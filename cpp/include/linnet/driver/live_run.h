// Live runs from the sensor module: the UDP driver feeding a StreamRun in real-time mode (late frames dropped), and
// the recorder that writes the stream as a EuRoC folder (so that a live session can be replayed with `linnet run`).
#pragma once

#include <functional>
#include <string>

#include "linnet/driver/udp_driver.h"
#include "linnet/pipeline/dataset_runner.h"

namespace linnet {

struct LiveOptions {
  std::string host = "127.0.0.1";  // address to listen on
  int port = 0;
  double duration_s = -1.0;        // stop after this long (wall time from the first packet; < 0: until idle / stop)
  std::string record_dir;          // also write the stream as a EuRoC folder here ("" : no)
  bool run_system = true;          // false: record only (`linnet sensor record`)
};

/// What the main loop sees while running (for a status line).
struct LiveStatus {
  double elapsed_s = 0.0;
  int frames = 0;                 // frames delivered by the driver
  int processed = 0;              // frames the estimator processed
  int dropped = 0;                // frames the System could not take in time
  std::uint64_t lost_rows = 0;    // both cameras
  std::uint64_t imu_samples = 0;
  std::string tracking = "waiting";  // "initialising" / "tracking" / "lost" of the newest processed frame
};

struct LiveResult {
  RunSummary summary;          // empty (no frames) when run_system is false
  DriverCounters counters;
  int recorded_frames = 0, recorded_imu = 0;
  std::string end_reason;      // "duration", "idle", "stopped"
};

/// Listens on the options' port (bound when this returns control through `on_ready(port)`), runs until the
/// duration, `idle_timeout_s` without packets (after the first), or `should_stop()`; then stops the driver, finishes
/// the System and returns everything. `status` is called about twice a second on the calling thread.
LiveResult runLive(const Config& config, const LiveOptions& options, const std::function<void(int)>& on_ready,
                   const std::function<bool()>& should_stop, const std::function<void(const LiveStatus&)>& status);

}  // namespace linnet
