// linnet_run: the C++ dataset runner, for machines without the Python package and for native profilers.
//   linnet_run DATASET [--out DIR] [--config FILE] [--set section.key=value]... [--max-frames N] [--start S]
// Runs a EuRoC folder in blocking (deterministic) mode, prints a one-line summary and, with --out, writes
// trajectory.tum, trajectory.csv, timing.csv and map.ply (the Python CLI `linnet run` adds summary.json and the APE).
// Exit codes as `linnet`: 0 ok, 1 bad data (the message names the file / key), 2 usage, 3 the run did not track
// (fewer than half of the processed frames have a pose).
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "linnet/core/error.h"
#include "linnet/pipeline/dataset_runner.h"

namespace {

int usage(const char* msg) {
  std::fprintf(stderr,
               "linnet_run: %s\nusage: linnet_run DATASET [--out DIR] [--config FILE] [--set section.key=value]... "
               "[--max-frames N] [--start S]\n",
               msg);
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  std::string dataset, out, config_file;
  std::vector<std::string> sets;
  linnet::RunOptions run;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw linnet::UsageError(a + " needs a value");
        return argv[++i];
      };
      if (a == "--out") {
        out = next();
      } else if (a == "--config") {
        config_file = next();
      } else if (a == "--set") {
        sets.push_back(next());
      } else if (a == "--max-frames") {
        run.max_frames = std::stoi(next());
      } else if (a == "--start") {
        run.start_s = std::stod(next());
      } else if (a == "-h" || a == "--help") {
        usage("run a EuRoC-format dataset");
        return 0;
      } else if (!a.empty() && a[0] == '-') {
        return usage(("unknown option " + a).c_str());
      } else if (dataset.empty()) {
        dataset = a;
      } else {
        return usage(("unexpected argument " + a).c_str());
      }
    }
    if (dataset.empty()) return usage("missing DATASET");
    for (const std::string& kv : sets)
      if (kv.find('=') == std::string::npos || kv.front() == '=')
        return usage(("--set needs section.key=value, got '" + kv + "'").c_str());
  } catch (const linnet::UsageError& e) {
    return usage(e.what());
  } catch (const std::exception&) {  // std::stoi / std::stod
    return usage("a numeric option got a non-number");
  }
  // The run: any error from here on is about the data or the config (exit code 1, no usage text).
  try {
    // As `linnet run`: defaults with the dataset's calibration, then the config file, then --set.
    linnet::Config cfg = linnet::configForEuroc(dataset, linnet::Config::eurocStereoImu());
    if (!config_file.empty()) cfg.merge(config_file);
    for (const std::string& kv : sets) {
      const std::size_t eq = kv.find('=');
      cfg.set(kv.substr(0, eq), kv.substr(eq + 1), "--set " + kv);
    }
    const linnet::RunSummary r = linnet::runEuroc(dataset, cfg, run);
    for (const std::string& w : r.warnings) std::fprintf(stderr, "linnet_run: warning: %s\n", w.c_str());
    std::printf("frames %d, with pose %d, init %.2f s, re-initialisations %d, wall %.2f s, CPU %.2f s (images %.2f s), "
                "real-time factor wall %.3f CPU %.3f\n",
                r.frames, r.frames_with_pose, r.init_time_s, r.reinitialisations, r.wall_time_s, r.cpu_time_s,
                r.image_load_cpu_s, r.real_time_factor, r.cpu_real_time_factor);
    if (r.extrinsics_estimated) {
      const linnet::Pose& c = r.extrinsics_correction;
      const linnet::Vec3 w = linnet::logSO3(c.q) * (180.0 / M_PI);
      std::printf("camera-IMU extrinsics refined online (T_B_R, cameras at T_B_R * T_B_Ci): rotation %.3f deg "
                  "[%.3f %.3f %.3f], translation %.2f mm [%.2f %.2f %.2f]\n",
                  w.norm(), w.x(), w.y(), w.z(), 1e3 * c.p.norm(), 1e3 * c.p.x(), 1e3 * c.p.y(), 1e3 * c.p.z());
    }
    if (r.stereo_correction_estimated) {
      const linnet::Pose& c = r.stereo_correction;
      const linnet::Vec3 w = linnet::logSO3(c.q) * (180.0 / M_PI);
      std::printf("cam1 refined online relative to cam0 (S, cam1 at T_B_R * T_B_C1 * S): rotation %.4f deg "
                  "[%.4f %.4f %.4f], translation %.3f mm\n",
                  w.norm(), w.x(), w.y(), w.z(), 1e3 * c.p.norm());
    }
    if (r.time_offset_estimated)
      std::printf("camera-to-IMU time offset estimated online: %.3f ms (camera stamp - capture time)\n",
                  1e3 * r.time_offset_s);
    if (r.line_adjustment.lines > 0)
      std::printf("line map adjustment: %zu of %zu lines joined into %zu, pose graph %s, CPU %.2f s\n",
                  r.line_adjustment.joined, r.line_adjustment.lines, r.line_adjustment.groups,
                  r.line_adjustment.solved ? "solved" : "not solved", r.line_adjustment.cpu_s);
    if (r.line_curation.input > 0)
      std::printf("line map: %zu lines published of %zu (estimator.lines.map.max_sigma_m); %ld new tracks "
                  "re-identified as window lines\n",
                  r.map_lines.size(), r.line_curation.input, r.reidentified_lines);
    if (r.loop_enabled) {
      double largest = 0.0;
      for (const linnet::LoopEvent& e : r.loops) largest = std::max(largest, e.correction_m);
      std::printf("loop closure: %zu loops, largest correction %.3f m; %zu keyframes, %zu graph nodes, %zu described, "
                  "%zu graph solves, place descriptions %.1f MB\n",
                  r.loops.size(), largest, r.loop_stats.keyframes, r.loop_stats.graph_nodes, r.loop_stats.described,
                  r.loop_stats.graph_solves, r.loop_stats.place_mb);
    }
    if (!out.empty()) linnet::writeRunOutputs(r, out);
    if (2 * r.frames_with_pose < r.processed_frames || r.processed_frames == 0) {
      std::fprintf(stderr, "linnet_run: tracking failed: %d of %d processed frames have a pose\n", r.frames_with_pose,
                   r.processed_frames);
      return 3;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "linnet_run: error: %s\n", e.what());
    return 1;
  }
}
