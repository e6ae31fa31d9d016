// Point front-end benchmark: per-frame time of PointTracker::track() on the EuRoC V1_01_easy micro set
// (95 stereo frames, 752x480), stereo and mono. Measures process CPU time (all threads), so that
// `taskset -c 0 linnet_bench --benchmark_filter=Points` gives the one-core cost.
//   LINNET_SHARED_DATA (default <source>/../shared/data) locates the data; the benchmark is skipped without it.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/features/point_tracker.h"

namespace {

using linnet::CameraCalibration;
using linnet::CameraModel;

std::filesystem::path microDir() {
  if (const char* env = std::getenv("LINNET_SHARED_DATA")) return std::filesystem::path(env) / "euroc" / "V1_01_easy_micro";
#ifdef LINNET_SOURCE_DIR
  return std::filesystem::path(LINNET_SOURCE_DIR) / ".." / "shared" / "data" / "euroc" / "V1_01_easy_micro";
#else
  return std::filesystem::path("..") / "shared" / "data" / "euroc" / "V1_01_easy_micro";
#endif
}

bool readCamera(const std::filesystem::path& yaml, CameraCalibration* c) {
  cv::FileStorage fs(yaml.string(), cv::FileStorage::READ);
  if (!fs.isOpened()) return false;
  std::vector<double> intr, dist, T;
  fs["intrinsics"] >> intr;
  fs["distortion_coefficients"] >> dist;
  fs["T_BS"]["data"] >> T;
  if (intr.size() != 4 || T.size() != 16) return false;
  c->intrinsics = {intr[0], intr[1], intr[2], intr[3]};
  c->distortion_coeffs = dist;
  linnet::Mat4 M;
  for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = T[static_cast<std::size_t>(i)];
  c->T_B_C = linnet::Pose::fromMatrix(M);
  return true;
}

struct Micro {
  bool ok = false;
  CameraCalibration c0, c1;
  std::vector<linnet::Timestamp> t;
  std::vector<cv::Mat> left, right;
};

const Micro& micro() {
  static const Micro m = [] {
    Micro m;
    const auto mav = microDir() / "mav0";
    if (!readCamera(mav / "cam0" / "sensor.yaml", &m.c0) || !readCamera(mav / "cam1" / "sensor.yaml", &m.c1))
      return m;
    std::ifstream csv(mav / "cam0" / "data.csv");
    std::string line;
    while (std::getline(csv, line)) {
      if (line.empty() || line[0] == '#') continue;
      const auto comma = line.find(',');
      std::string name = line.substr(comma + 1);
      while (!name.empty() && (name.back() == '\r' || name.back() == ' ')) name.pop_back();
      m.t.push_back(std::stoll(line.substr(0, comma)));
      m.left.push_back(cv::imread((mav / "cam0" / "data" / name).string(), cv::IMREAD_GRAYSCALE));
      m.right.push_back(cv::imread((mav / "cam1" / "data" / name).string(), cv::IMREAD_GRAYSCALE));
      if (m.left.back().empty() || m.right.back().empty()) return m;
    }
    m.ok = !m.t.empty();
    return m;
  }();
  return m;
}

// One iteration = one track() call; the tracker runs through the 95 frames and starts over (a fresh tracker, so the
// time stamps keep increasing) when they are used up.
void runTracker(benchmark::State& state, bool stereo, const char* detector, bool stereo_clahe = true) {
  const Micro& m = micro();
  if (!m.ok) {
    state.SkipWithError("EuRoC micro set not found (set LINNET_SHARED_DATA)");
    return;
  }
  const auto cam0 = CameraModel::create(m.c0);
  const auto cam1 = CameraModel::create(m.c1);
  const linnet::Pose T_C1_C0 = m.c1.T_B_C.inverse() * m.c0.T_B_C;
  linnet::PointTrackerOptions opt;
  opt.detector = detector;
  opt.stereo_clahe = stereo_clahe;
  auto tracker = std::make_unique<linnet::PointTracker>(opt, *cam0, stereo ? cam1.get() : nullptr, T_C1_C0);
  std::vector<linnet::PointObservation> obs;
  std::size_t k = 0;
  double points = 0.0, matched = 0.0;
  for (auto _ : state) {
    if (k == m.t.size()) {
      state.PauseTiming();
      tracker = std::make_unique<linnet::PointTracker>(opt, *cam0, stereo ? cam1.get() : nullptr, T_C1_C0);
      k = 0;
      state.ResumeTiming();
    }
    obs.clear();
    tracker->track(m.t[k], m.left[k], stereo ? m.right[k] : cv::Mat(), &obs);
    points += static_cast<double>(obs.size());
    matched += tracker->lastStats().stereo_matched;
    ++k;
    benchmark::DoNotOptimize(obs.data());
  }
  state.counters["points"] = benchmark::Counter(points, benchmark::Counter::kAvgIterations);
  state.counters["stereo"] = benchmark::Counter(matched, benchmark::Counter::kAvgIterations);
}

void BM_PointsStereoFast(benchmark::State& s) { runTracker(s, true, "fast"); }
void BM_PointsMonoFast(benchmark::State& s) { runTracker(s, false, "fast"); }
void BM_PointsStereoShiTomasi(benchmark::State& s) { runTracker(s, true, "shi_tomasi"); }
void BM_PointsStereoNoStereoClahe(benchmark::State& s) { runTracker(s, true, "fast", false); }

BENCHMARK(BM_PointsStereoFast)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->Iterations(190);
BENCHMARK(BM_PointsMonoFast)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->Iterations(190);
BENCHMARK(BM_PointsStereoShiTomasi)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->Iterations(190);
BENCHMARK(BM_PointsStereoNoStereoClahe)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime()->Iterations(190);

}  // namespace
