// linnet_run: the C++ dataset runner, for machines without the Python package and for native profilers.
//   linnet_run DATASET [--out DIR] [--config FILE] [--set section.key=value]... [--max-frames N] [--start S]
// Runs a EuRoC folder in blocking (deterministic) mode, prints a one-line summary and, with --out, writes
// trajectory.tum, trajectory.csv, timing.csv and map.ply (the Python CLI `linnet run` adds summary.json and the APE).
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

// "a.b.c=v" -> YAML text "a:\n  b:\n    c: v\n".
std::string setToYaml(const std::string& kv) {
  const std::size_t eq = kv.find('=');
  if (eq == std::string::npos || eq == 0) throw linnet::UsageError("--set needs section.key=value, got '" + kv + "'");
  const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
  std::string yaml, indent;
  std::size_t start = 0;
  for (;;) {
    const std::size_t dot = key.find('.', start);
    const std::string part = key.substr(start, dot == std::string::npos ? std::string::npos : dot - start);
    if (dot == std::string::npos) {
      yaml += indent + part + ": " + value + "\n";
      break;
    }
    yaml += indent + part + ":\n";
    indent += "  ";
    start = dot + 1;
  }
  return yaml;
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
    // As `linnet run`: defaults with the dataset's calibration, then the config file, then --set.
    linnet::Config cfg = linnet::configForEuroc(dataset, linnet::Config::eurocStereoImu());
    if (!config_file.empty()) cfg.merge(config_file);
    for (const std::string& s : sets) cfg.mergeYaml(setToYaml(s), "--set " + s);
    cfg.validate();
    const linnet::RunSummary r = linnet::runEuroc(dataset, cfg, run);
    std::printf("frames %d, with pose %d, init %.2f s, re-initialisations %d, wall %.2f s, CPU %.2f s (images %.2f s), "
                "real-time factor wall %.3f CPU %.3f\n",
                r.frames, r.frames_with_pose, r.init_time_s, r.reinitialisations, r.wall_time_s, r.cpu_time_s,
                r.image_load_cpu_s, r.real_time_factor, r.cpu_real_time_factor);
    if (!out.empty()) linnet::writeRunOutputs(r, out);
    return 0;
  } catch (const linnet::UsageError& e) {
    return usage(e.what());
  } catch (const std::invalid_argument&) {
    return usage("a numeric option got a non-number");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "linnet_run: %s\n", e.what());
    return 1;
  }
}
