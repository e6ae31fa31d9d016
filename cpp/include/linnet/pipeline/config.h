// The root configuration: one options struct per module, loaded from and saved to YAML by the same code.
#pragma once

#include <string>

#include "linnet/camera/camera_model.h"
#include "linnet/estimator/estimator.h"
#include "linnet/features/line_tracker.h"
#include "linnet/features/point_tracker.h"
#include "linnet/imu/imu_types.h"
#include "linnet/io/sensor_protocol.h"
#include "linnet/loop/loop_options.h"

namespace linnet {

/// How the System's stages run.
struct PipelineOptions {
  bool blocking = true;                // true: never drop a frame, same input -> same output (dataset runs);
                                       // false: real-time, frames are dropped when the front-end is behind
  int frame_queue_capacity = 4;        // frames waiting for the front-end
  int observation_queue_capacity = 4;  // front-end results waiting for the estimator
  bool use_lines = true;               // run the line front-end; the estimator uses its lines (estimator.lines).
                                       // Low-texture replays: APE x0.5-0.7 and no re-initialisations (README)
  bool parallel_frontend = true;       // points and lines in two workers (else one after the other). A process
                                       // restricted to one CPU (taskset) runs them one after the other anyway:
                                       // 1-2 % less CPU (fewer thread switches), the same outputs

  template <class V>
  void visit(V& v) {
    v("blocking", blocking, "never drop frames; deterministic (dataset runs)");
    v("frame_queue_capacity", frame_queue_capacity, "frames waiting for the front-end", 1, 1000);
    v("observation_queue_capacity", observation_queue_capacity, "frames waiting for the estimator", 1, 1000);
    v("use_lines", use_lines, "run the line front-end (lines in the estimator)");
    v("parallel_frontend", parallel_frontend, "points and lines in two worker threads (not on a single allowed CPU)");
  }
};

/// Everything a System needs. Defaults: EuRoC's stereo-inertial rig (ADIS16448 + two MT9V034 cameras).
struct Config {
  CameraCalibration cam0;          // left camera
  CameraCalibration cam1;          // right camera (ignored when stereo = false)
  bool stereo = true;              // stereo + IMU (else monocular + IMU)
  ImuNoise imu;
  PointTrackerOptions points;
  LineTrackerOptions lines;
  EstimatorOptions estimator;
  LoopOptions loop;                // loop closure (stereo only)
  PipelineOptions pipeline;
  SensorOptions sensor;            // the stereo-IMU sensor module's stream and driver (linnet live)

  template <class V>
  void visit(V& v) {
    v.section("cam0", cam0);
    v.section("cam1", cam1);
    v("stereo", stereo, "stereo + IMU (false: monocular + IMU)");
    v.section("imu", imu);
    v.section("points", points);
    v.section("lines", lines);
    v.section("estimator", estimator);
    v.section("loop", loop);
    v.section("pipeline", pipeline);
    v.section("sensor", sensor);
  }

  /// EuRoC stereo-inertial defaults (calibration of the EuRoC MAV's rig).
  static Config eurocStereoImu();
  /// Defaults, then every key present in the YAML file. Throws InputError / ConfigError naming file, line and key.
  static Config load(const std::string& path);
  /// Same, from YAML text (`source` names it in error messages).
  static Config fromYaml(const std::string& text, const std::string& source = "<yaml>");
  /// Overrides keys present in the YAML file / text on this config.
  void merge(const std::string& path);
  void mergeYaml(const std::string& text, const std::string& source = "<yaml>");
  /// Sets one key: `dotted_key` like "pipeline.use_lines", `yaml_value` a YAML value ("true", "0.5", "[1, 2]").
  /// Errors name `source` (default: the key) without a line number: the key was not in a file.
  void set(const std::string& dotted_key, const std::string& yaml_value, const std::string& source = "");
  /// Writes every key with its documentation; load(save(c)) == c.
  void save(const std::string& path) const;
  /// The YAML text of every key; with `comments`, each key's documentation and range too (as save writes).
  std::string toYaml(bool comments = false) const;
  /// Throws ConfigError naming the first key out of range.
  void validate() const;
};

}  // namespace linnet
