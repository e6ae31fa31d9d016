// Line front-end benchmark on the EuRoC V1_01_easy micro set (95 stereo frames, 752x480): per-frame time of
// LineTracker::track() (stereo, mono), of each detector alone, and of the LBD descriptor. Process CPU time;
// `taskset -c 1 linnet_bench --benchmark_filter=Lines` gives the one-core cost.
//   LINNET_SHARED_DATA (default <source>/../shared/data) locates the data; the benchmark is skipped without it.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/features/line_detector.h"
#include "linnet/features/line_lbd.h"
#include "linnet/features/line_tracker.h"

namespace {

std::filesystem::path linesMicroDir() {
  if (const char* env = std::getenv("LINNET_SHARED_DATA"))
    return std::filesystem::path(env) / "euroc" / "V1_01_easy_micro";
#ifdef LINNET_SOURCE_DIR
  return std::filesystem::path(LINNET_SOURCE_DIR) / ".." / "shared" / "data" / "euroc" / "V1_01_easy_micro";
#else
  return std::filesystem::path("..") / "shared" / "data" / "euroc" / "V1_01_easy_micro";
#endif
}

bool linesReadCamera(const std::filesystem::path& yaml, linnet::CameraCalibration* c) {
  cv::FileStorage fs(yaml.string(), cv::FileStorage::READ);
  if (!fs.isOpened()) return false;
  std::vector<double> intr, dist, T;
  fs["intrinsics"] >> intr;
  fs["distortion_coefficients"] >> dist;
  fs["T_BS"]["data"] >> T;
  if (intr.size() != 4 || T.size() != 16) return false;
  c->intrinsics = {intr[0], intr[1], intr[2], intr[3]};
  c->distortion = "radtan";
  c->distortion_coeffs = dist;
  linnet::Mat4 M;
  for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = T[static_cast<std::size_t>(i)];
  c->T_B_C = linnet::Pose::fromMatrix(M);
  return true;
}

struct LinesMicro {
  bool ok = false;
  linnet::CameraCalibration c0, c1;
  std::vector<linnet::Timestamp> t;
  std::vector<cv::Mat> left, right;
};

const LinesMicro& linesMicro() {
  static const LinesMicro m = [] {
    LinesMicro m;
    const auto mav = linesMicroDir() / "mav0";
    if (!linesReadCamera(mav / "cam0" / "sensor.yaml", &m.c0) || !linesReadCamera(mav / "cam1" / "sensor.yaml", &m.c1))
      return m;
    std::ifstream in(mav / "cam0" / "data.csv");
    std::string line;
    while (std::getline(in, line)) {
      if (line.empty() || line[0] == '#') continue;
      const auto comma = line.find(',');
      std::string name = line.substr(comma + 1);
      while (!name.empty() && (name.back() == '\r' || name.back() == ' ')) name.pop_back();
      cv::Mat l = cv::imread((mav / "cam0" / "data" / name).string(), cv::IMREAD_GRAYSCALE);
      cv::Mat r = cv::imread((mav / "cam1" / "data" / name).string(), cv::IMREAD_GRAYSCALE);
      if (l.empty() || r.empty()) return m;
      m.t.push_back(std::stoll(line.substr(0, comma)));
      m.left.push_back(l);
      m.right.push_back(r);
    }
    m.ok = !m.left.empty();
    return m;
  }();
  return m;
}

void runTracker(benchmark::State& state, bool stereo, const std::string& detector) {
  const LinesMicro& m = linesMicro();
  if (!m.ok) {
    state.SkipWithError("EuRoC micro set not found (set LINNET_SHARED_DATA)");
    return;
  }
  const auto cam0 = linnet::CameraModel::create(m.c0), cam1 = linnet::CameraModel::create(m.c1);
  const linnet::Pose T_C1_C0 = m.c1.T_B_C.inverse() * m.c0.T_B_C;
  linnet::LineTrackerOptions opt;
  opt.detection.detector = detector;
  opt.detection.downsample = (detector == "edlines" || detector == "fld") ? 2.0 : 1.0;
  auto tracker = std::make_unique<linnet::LineTracker>(opt, *cam0, stereo ? cam1.get() : nullptr, T_C1_C0);
  std::size_t k = 0;
  std::int64_t offset = 0;
  double lines = 0.0, frames = 0.0;
  std::vector<linnet::LineObservation> obs;
  for (auto _ : state) {
    if (k == m.left.size()) {  // wrap around: keep time increasing
      k = 0;
      offset += m.t.back() - m.t.front() + 50'000'000;
    }
    obs.clear();
    tracker->track(m.t[k] + offset, m.left[k], stereo ? m.right[k] : cv::Mat(), &obs);
    lines += static_cast<double>(obs.size());
    frames += 1.0;
    ++k;
  }
  state.counters["lines"] = frames > 0 ? lines / frames : 0.0;
}

void BM_LinesTrackStereo(benchmark::State& state) { runTracker(state, true, "ed"); }
void BM_LinesTrackStereoEdlines(benchmark::State& state) { runTracker(state, true, "edlines"); }
void BM_LinesTrackMono(benchmark::State& state) { runTracker(state, false, "ed"); }
void BM_LinesTrackStereoFld(benchmark::State& state) { runTracker(state, true, "fld"); }
void BM_LinesTrackStereoLsd(benchmark::State& state) { runTracker(state, true, "lsd"); }

void runDetector(benchmark::State& state, const std::string& detector, int downsample) {
  const LinesMicro& m = linesMicro();
  if (!m.ok) {
    state.SkipWithError("EuRoC micro set not found (set LINNET_SHARED_DATA)");
    return;
  }
  linnet::LineDetectorOptions opt;
  opt.detector = detector;
  opt.downsample = downsample;
  linnet::LineDetector det(opt);
  std::vector<linnet::LineSegment> segs;
  std::size_t k = 0;
  double n = 0.0, frames = 0.0;
  for (auto _ : state) {
    det.detect(m.left[k], &segs);
    n += static_cast<double>(segs.size());
    frames += 1.0;
    k = (k + 1) % m.left.size();
  }
  state.counters["segments"] = frames > 0 ? n / frames : 0.0;
}

void BM_LinesDetectEdlinesHalf(benchmark::State& state) { runDetector(state, "edlines", 2); }
void BM_LinesDetectEdlinesFull(benchmark::State& state) { runDetector(state, "edlines", 1); }
void BM_LinesDetectFldHalf(benchmark::State& state) { runDetector(state, "fld", 2); }
void BM_LinesDetectLsd(benchmark::State& state) { runDetector(state, "lsd", 1); }
void BM_LinesDetectEdFull(benchmark::State& state) { runDetector(state, "ed", 1); }

// Edge Drawing + line fit alone (no refinement, orientation or parallel edges), full resolution; arguments: anchor
// threshold, scan interval.
void BM_LinesEdgeDrawingRaw(benchmark::State& state) {
  const LinesMicro& m = linesMicro();
  if (!m.ok) {
    state.SkipWithError("EuRoC micro set not found (set LINNET_SHARED_DATA)");
    return;
  }
  linnet::EdgeDrawingOptions opt;
  opt.anchor_threshold = static_cast<int>(state.range(0));
  opt.scan_interval = static_cast<int>(state.range(1));
  linnet::EdgeDrawing ed(opt);
  std::vector<cv::Vec4f> lines;
  std::size_t k = 0;
  double n = 0.0, frames = 0.0;
  for (auto _ : state) {
    ed.detect(m.left[k], &lines);
    n += static_cast<double>(lines.size());
    frames += 1.0;
    k = (k + 1) % m.left.size();
  }
  state.counters["lines"] = frames > 0 ? n / frames : 0.0;
}

void BM_LinesLbd100(benchmark::State& state) {
  const LinesMicro& m = linesMicro();
  if (!m.ok) {
    state.SkipWithError("EuRoC micro set not found (set LINNET_SHARED_DATA)");
    return;
  }
  linnet::LineDetectorOptions opt;
  opt.max_segments = 100;
  linnet::LineDetector det(opt);
  std::vector<linnet::LineSegment> segs;
  det.detect(m.left[0], &segs);
  std::vector<linnet::LbdDescriptor> desc;
  for (auto _ : state) {
    linnet::computeLbd(m.left[0], linnet::LbdOptions{}, segs, &desc);
    benchmark::DoNotOptimize(desc.data());
  }
  state.counters["segments"] = static_cast<double>(segs.size());
}

}  // namespace

BENCHMARK(BM_LinesTrackStereo)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesTrackStereoEdlines)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesTrackMono)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesTrackStereoFld)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesTrackStereoLsd)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesDetectEdlinesHalf)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesDetectEdlinesFull)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesDetectFldHalf)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesDetectEdFull)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesEdgeDrawingRaw)->Args({0, 1})->Args({8, 1})->Args({0, 2})->Args({8, 2})->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesDetectLsd)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
BENCHMARK(BM_LinesLbd100)->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();
