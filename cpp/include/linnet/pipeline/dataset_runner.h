// Runs a EuRoC-format dataset through a System in time order (blocking mode: deterministic).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "linnet/pipeline/config.h"
#include "linnet/pipeline/system.h"

namespace linnet {

struct RunOptions {
  int max_frames = -1;         // stop after this many stereo frames (-1: all)
  double start_s = 0.0;        // skip the images of the first start_s seconds (s)
  std::function<void(int done, int total)> progress;  // called after each frame is handed to the System
};

struct RunSummary {
  int frames = 0;                 // frames handed to the System
  int processed_frames = 0;       // frames the estimator processed
  int frames_with_pose = 0;       // of which with a pose (initialised)
  int dropped_frames = 0;         // real-time mode drops / frames without IMU coverage
  double init_time_s = -1.0;      // data time from the first image to the first pose (-1: never initialised)
  int reinitialisations = 0;
  double wall_time_s = 0.0;       // wall-clock time of the run (image loading included)
  double sequence_duration_s = 0.0;  // data time spanned by the images that were run
  double real_time_factor = 0.0;  // wall_time_s / sequence_duration_s
  double cpu_time_s = 0.0;        // CPU time of the whole process during the run, every thread (s)
  double cpu_real_time_factor = 0.0;  // cpu_time_s / sequence_duration_s: what the run costs on one core
  double image_load_cpu_s = 0.0;  // CPU time spent reading and decoding the images (s), part of cpu_time_s
  std::vector<FrameResult> results;
  std::vector<Vec3> map_points;
  std::vector<MapLine> map_lines;
};

/// The config for a EuRoC folder: `base` with cam0/cam1/imu calibration replaced by the dataset's sensor.yaml.
Config configForEuroc(const std::string& dataset_path, const Config& base);

/// Runs the dataset. Throws InputError for unreadable data (naming the file), ConfigError for a bad config.
RunSummary runEuroc(const std::string& dataset_path, const Config& config, const RunOptions& options = {});

/// Writes DIR/trajectory.tum (a pose per frame with a pose, body frame, seconds), DIR/trajectory.csv (EuRoC style
/// with velocity and biases), DIR/timing.csv (per frame ms), DIR/map.ply (points and line segments as PLY edges) and
/// DIR/map_lines.csv (`id,x0,y0,z0,x1,y1,z1,observations`, W, metres). Creates DIR.
void writeRunOutputs(const RunSummary& summary, const std::string& out_dir);

}  // namespace linnet
