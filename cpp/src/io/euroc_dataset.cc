#include "linnet/io/euroc_dataset.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <string_view>
#include <unordered_set>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "linnet/core/error.h"
#include "linnet/io/config_yaml.h"
#include "linnet/io/png_gray.h"
#include "linnet/io/text_parse.h"
#include "linnet/io/yaml_values.h"

namespace linnet {
namespace fs = std::filesystem;
namespace {

bool isIdentity(const Pose& T, double tol = 1e-9) {
  return (T.matrix() - Mat4::Identity()).cwiseAbs().maxCoeff() < tol;
}

/// File names in a folder (one listing instead of one stat per image).
std::unordered_set<std::string> listFileNames(const fs::path& dir) {
  std::unordered_set<std::string> names;
  std::error_code ec;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec))
    names.insert(it->path().filename().string());
  return names;
}

struct CameraStream {
  CameraCalibration calib;
  std::vector<CameraCsvRow> rows;
  fs::path data_dir;
  std::size_t missing_images = 0;  // dropped because the file is missing (drop_missing_images)
};

/// Reads camN/data.csv and checks its images; the calibration comes from camN/sensor.yaml unless given.
CameraStream readCameraStream(const fs::path& cam_dir, const EurocOpenOptions& options,
                              const CameraCalibration* calib) {
  CameraStream s;
  const fs::path csv = cam_dir / "data.csv";
  if (calib != nullptr) {
    s.calib = *calib;
  } else if (options.read_calibration) {
    s.calib = readCameraSensorYaml((cam_dir / "sensor.yaml").string());
  }
  s.rows = readCameraCsv(csv.string(), options.threads);
  s.data_dir = cam_dir / "data";
  if (options.check_images) {
    std::error_code ec;
    if (!fs::is_directory(s.data_dir, ec))
      io::failInput(s.data_dir.string(), 0, "image folder not found (listed by " + csv.string() + ")");
    const std::unordered_set<std::string> names = listFileNames(s.data_dir);
    std::vector<CameraCsvRow> kept;
    kept.reserve(s.rows.size());
    for (CameraCsvRow& r : s.rows) {
      const bool plain = r.filename.find('/') == std::string::npos;
      const bool found = plain ? names.count(r.filename) > 0 : fs::exists(s.data_dir / r.filename, ec);
      if (found) {
        kept.push_back(std::move(r));
      } else if (options.drop_missing_images) {
        ++s.missing_images;
      } else {
        io::failInput(csv.string(), r.line, "image not found on disk: " + (s.data_dir / r.filename).string());
      }
    }
    s.rows = std::move(kept);
  }
  return s;
}

/// Median frame interval -> rate (for calibrations that do not hold it, like Kalibr camchains).
double rateFromTimestamps(const std::vector<CameraCsvRow>& rows, double fallback) {
  if (rows.size() < 2) return fallback;
  std::vector<Timestamp> dt;
  dt.reserve(rows.size() - 1);
  for (std::size_t i = 1; i < rows.size(); ++i) dt.push_back(rows[i].t - rows[i - 1].t);
  std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
  const Timestamp median = dt[dt.size() / 2];
  return median > 0 ? 1e9 / static_cast<double>(median) : fallback;
}

}  // namespace

std::vector<CameraCsvRow> readCameraCsv(const std::string& path, int max_threads) {
  const io::TextFile file = io::TextFile::read(path);
  auto parse = [](const io::TextLines& lines, std::string_view line) {
    std::string_view f[2];
    const int n = io::splitFields(line, ',', f, 2);
    if (n != 2) lines.fail("expected 2 columns 'timestamp [ns],filename', got " + std::to_string(n));
    CameraCsvRow r;
    r.t = io::parseInt64Field(lines, f[0], "timestamp [ns]");
    if (f[1].empty()) lines.fail("empty file name");
    r.filename = std::string(f[1]);
    r.line = lines.line();
    return r;
  };
  std::vector<CameraCsvRow> rows =
      io::parseRows<CameraCsvRow>(file, io::parseThreads(file.sizeBytes(), max_threads), parse, 44);
  io::checkStrictlyIncreasing(file, rows, [](const CameraCsvRow& r) { return r.t; });
  return rows;
}

std::vector<ImuSample> readImuCsv(const std::string& path, int max_threads) {
  const io::TextFile file = io::TextFile::read(path);
  static const char* kNames[7] = {"timestamp [ns]", "w_RS_S_x", "w_RS_S_y", "w_RS_S_z",
                                  "a_RS_S_x",       "a_RS_S_y", "a_RS_S_z"};
  auto parse = [](const io::TextLines& lines, std::string_view line) {
    std::string_view f[7];
    const int n = io::splitFields(line, ',', f, 7);
    if (n != 7)
      lines.fail("expected 7 columns 'timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z', got " + std::to_string(n));
    ImuSample s;
    s.t = io::parseInt64Field(lines, f[0], kNames[0]);
    double v[6];
    for (int i = 0; i < 6; ++i) v[i] = io::parseDoubleField(lines, f[i + 1], kNames[i + 1]);
    s.gyr = Vec3(v[0], v[1], v[2]);
    s.acc = Vec3(v[3], v[4], v[5]);
    return s;
  };
  std::vector<ImuSample> samples =
      io::parseRows<ImuSample>(file, io::parseThreads(file.sizeBytes(), max_threads), parse, 120);
  io::checkStrictlyIncreasing(file, samples, [](const ImuSample& s) { return s.t; });
  return samples;
}

EurocDataset EurocDataset::open(const std::string& path, const EurocOpenOptions& options) {
  std::error_code ec;
  const fs::path p(path);
  if (!fs::exists(p, ec)) io::failInput(path, 0, "dataset folder not found");
  if (!fs::is_directory(p, ec))
    io::failInput(path, 0, "is not a folder (expected a EuRoC folder holding mav0/)");
  fs::path mav0;
  if (fs::is_directory(p / "mav0", ec)) {
    mav0 = p / "mav0";
  } else if (fs::is_directory(p / "cam0", ec)) {
    mav0 = p;
  } else {
    io::failInput(path, 0,
                  "no mav0/ folder (expected the EuRoC ASL layout " +
                      (p / "mav0" / "cam0" / "data.csv").string() + ")");
  }

  EurocDataset d;
  d.mav0_ = mav0.string();

  // IMU first: the body frame is the IMU frame.
  Pose T_B_I;
  const std::string imu_yaml =
      options.imu_yaml.empty() ? (mav0 / "imu0" / "sensor.yaml").string() : options.imu_yaml;
  if (options.read_calibration || !options.imu_yaml.empty()) d.imu_noise_ = readImuSensorYaml(imu_yaml, &T_B_I);
  d.imu_ = readImuCsv((mav0 / "imu0" / "data.csv").string(), options.threads);
  if (d.imu_.empty()) io::failInput((mav0 / "imu0" / "data.csv").string(), 0, "no IMU samples");
  const Pose T_I_B = T_B_I.inverse();
  if (!isIdentity(T_B_I) && options.camchain.empty())
    d.warnings_.push_back("imu0 T_BS is not the identity: camera extrinsics re-expressed in the IMU frame");
  const auto gaps = [&] {
    std::size_t count = 0;
    const double max_dt_ns = 3.0e9 / d.imu_noise_.rate_hz;
    for (std::size_t i = 1; i < d.imu_.size(); ++i)
      if (static_cast<double>(d.imu_[i].t - d.imu_[i - 1].t) > max_dt_ns) ++count;
    return count;
  }();
  if (gaps > 0) d.warnings_.push_back("imu0: " + std::to_string(gaps) + " gaps longer than 3 sample periods");

  // Camera calibration: camN/sensor.yaml (extrinsics w.r.t. the EuRoC body frame), or a Kalibr camchain
  // (extrinsics w.r.t. the IMU already).
  KalibrCamchain chain;
  if (!options.camchain.empty()) chain = readKalibrCamchain(options.camchain);
  const auto calibOf = [&](std::size_t i) -> const CameraCalibration* {
    if (options.camchain.empty()) return nullptr;
    if (i >= chain.cameras.size())
      io::failInput(options.camchain, 0,
                    "missing key 'cam" + std::to_string(i) + "' for the dataset's cam" + std::to_string(i));
    return &chain.cameras[i];
  };
  const auto toImuFrame = [&](CameraStream& cam) {
    if (options.camchain.empty()) {
      cam.calib.T_B_C = T_I_B * cam.calib.T_B_C;
    } else {
      cam.calib.rate_hz = rateFromTimestamps(cam.rows, cam.calib.rate_hz);
    }
  };
  const auto reportMissing = [&](const CameraStream& cam, const char* name) {
    if (cam.missing_images > 0)
      d.warnings_.push_back(std::string(name) + ": dropped " + std::to_string(cam.missing_images) +
                            " rows whose image file is missing");
  };

  CameraStream cam0 = readCameraStream(mav0 / "cam0", options, calibOf(0));
  toImuFrame(cam0);
  reportMissing(cam0, "cam0");
  d.cam0_ = cam0.calib;
  if (cam0.rows.empty()) io::failInput((mav0 / "cam0" / "data.csv").string(), 0, "no images listed");

  // A camchain with one camera makes the dataset monocular even if it has a cam1 folder.
  const bool want_cam1 = options.use_cam1 && fs::is_directory(mav0 / "cam1", ec) &&
                         (options.camchain.empty() || chain.cameras.size() >= 2);
  if (!want_cam1) {
    d.frames_.reserve(cam0.rows.size());
    for (const auto& r : cam0.rows) d.frames_.push_back({r.t, (cam0.data_dir / r.filename).string(), ""});
  } else {
    CameraStream cam1 = readCameraStream(mav0 / "cam1", options, calibOf(1));
    toImuFrame(cam1);
    reportMissing(cam1, "cam1");
    d.cam1_ = cam1.calib;
    d.has_cam1_ = true;
    // Pair by exact time stamp (both lists strictly increase): a merge.
    std::size_t i = 0, j = 0, only0 = 0, only1 = 0;
    d.frames_.reserve(std::min(cam0.rows.size(), cam1.rows.size()));
    while (i < cam0.rows.size() && j < cam1.rows.size()) {
      if (cam0.rows[i].t == cam1.rows[j].t) {
        d.frames_.push_back({cam0.rows[i].t, (cam0.data_dir / cam0.rows[i].filename).string(),
                             (cam1.data_dir / cam1.rows[j].filename).string()});
        ++i;
        ++j;
      } else if (cam0.rows[i].t < cam1.rows[j].t) {
        ++i;
        ++only0;
      } else {
        ++j;
        ++only1;
      }
    }
    only0 += cam0.rows.size() - i;
    only1 += cam1.rows.size() - j;
    if (only0 + only1 > 0)
      d.warnings_.push_back("cam0/cam1: dropped " + std::to_string(only0 + only1) +
                            " frames without a partner at the same time stamp (cam0 " +
                            std::to_string(only0) + ", cam1 " + std::to_string(only1) + ")");
    if (d.frames_.empty())
      io::failInput(
          d.mav0_, 0,
          "cam0 and cam1 share no time stamp: no stereo frame (open with use_cam1 = false for mono)");
  }
  if (!chain.timeshift_cam_imu_s.empty() && chain.timeshift_cam_imu_s[0] != 0.0) {
    // Kalibr: t_imu = t_cam + timeshift_cam_imu. Frames are reported on the IMU clock.
    const Timestamp shift = fromSeconds(chain.timeshift_cam_imu_s[0]);
    for (auto& f : d.frames_) f.t += shift;
    d.warnings_.push_back("image time stamps shifted by " + std::to_string(shift) +
                          " ns onto the IMU clock (camchain timeshift_cam_imu)");
  }
  // Images outside the IMU log's span: the runner (dataset_runner.cc) names the files, the times and what it skips.

  const fs::path gt_dir = mav0 / "state_groundtruth_estimate0";
  if (options.load_ground_truth && fs::exists(gt_dir / "data.csv", ec)) {
    d.ground_truth_ = readEurocCsv((gt_dir / "data.csv").string(), options.threads);
    Pose T_B_S;
    if (fs::exists(gt_dir / "sensor.yaml", ec)) {
      const std::string gt_yaml = (gt_dir / "sensor.yaml").string();
      const YAML::Node root = loadYamlFile(gt_yaml);
      if (root.IsMap() && root["T_BS"])
        yaml::decode(root["T_BS"], yaml::Context{gt_yaml, "T_BS", true}, T_B_S);
    }
    // Rows give T_W_S of the tracked sensor S; the body (IMU) pose is T_W_I = T_W_S * T_S_B * T_B_I.
    const Pose T_S_I = T_B_S.inverse() * T_B_I;
    if (!isIdentity(T_S_I)) {
      for (auto& g : d.ground_truth_) g.T_W_B = g.T_W_B * T_S_I;
      d.warnings_.push_back(
          "ground truth re-expressed in the IMU frame (poses only; velocities are of the tracked "
          "sensor)");
    }
  }
  return d;
}

CameraRig EurocDataset::rig() const {
  CameraRig r;
  r.cameras.push_back(cam0_);
  if (has_cam1_) r.cameras.push_back(cam1_);
  return r;
}

double EurocDataset::durationSeconds() const {
  if (frames_.size() < 2) return 0.0;
  return toSeconds(frames_.back().t - frames_.front().t);
}

std::pair<std::size_t, std::size_t> EurocDataset::imuRange(Timestamp t0, Timestamp t1) const {
  const auto lo =
      std::lower_bound(imu_.begin(), imu_.end(), t0, [](const ImuSample& s, Timestamp t) { return s.t < t; });
  const auto hi =
      std::upper_bound(lo, imu_.end(), t1, [](Timestamp t, const ImuSample& s) { return t < s.t; });
  return {static_cast<std::size_t>(lo - imu_.begin()), static_cast<std::size_t>(hi - imu_.begin())};
}

bool EurocDataset::groundTruthAt(Timestamp t, GroundTruthState* state, Timestamp max_gap_ns) const {
  const auto& g = ground_truth_;
  if (g.empty() || t < g.front().t || t > g.back().t) return false;
  const auto it =
      std::lower_bound(g.begin(), g.end(), t, [](const GroundTruthState& s, Timestamp x) { return s.t < x; });
  if (it->t == t) {
    *state = *it;
    return true;
  }
  const GroundTruthState& b = *it;
  const GroundTruthState& a = *(it - 1);
  if (b.t - a.t > max_gap_ns) return false;
  const double u = static_cast<double>(t - a.t) / static_cast<double>(b.t - a.t);
  GroundTruthState s;
  s.t = t;
  s.T_W_B = Pose(a.T_W_B.q.slerp(u, b.T_W_B.q), (1.0 - u) * a.T_W_B.p + u * b.T_W_B.p);
  s.v_W = (1.0 - u) * a.v_W + u * b.v_W;
  s.b_g = (1.0 - u) * a.b_g + u * b.b_g;
  s.b_a = (1.0 - u) * a.b_a + u * b.b_a;
  s.has_velocity_bias = a.has_velocity_bias && b.has_velocity_bias;
  *state = s;
  return true;
}

cv::Mat EurocDataset::loadImage(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) io::failInput(path, 0, "image file not found");
  // The whole file in one read, then decoded from memory: cv::imread's decoder pulls the file through small
  // buffered reads, whose system calls cost as much as the decoding of an uncompressed PNG.
  // The buffer is left uninitialised for the read to fill (a vector would first zero every byte of every image).
  std::unique_ptr<unsigned char[]> bytes;
  std::streamoff size = -1;
  {
    std::ifstream file(path, std::ios::binary | std::ios::ate);
    size = file ? static_cast<std::streamoff>(file.tellg()) : -1;
    if (size < 0) io::failInput(path, 0, "cannot read image file");
    if (size == 0) io::failInput(path, 0, "cannot decode image (empty file)");
    if (size > std::numeric_limits<int>::max()) io::failInput(path, 0, "image file too large");
    bytes = std::make_unique_for_overwrite<unsigned char[]>(static_cast<std::size_t>(size));
    file.seekg(0);
    if (!file.read(reinterpret_cast<char*>(bytes.get()), size)) io::failInput(path, 0, "cannot read image file");
  }
  cv::Mat img;
  // Greyscale PNG (every EuRoC and replay image) straight through libpng without its checksums; anything else
  // through OpenCV's decoders.
  std::string png_error;
  switch (decodeGray8Png(bytes.get(), static_cast<std::size_t>(size), &img, &png_error)) {
    case PngGrayResult::kDecoded:
      return img;
    case PngGrayResult::kCorrupt:
      io::failInput(path, 0, "cannot decode image (PNG: " + png_error + ")");
    case PngGrayResult::kNotHandled:
      break;
  }
  try {
    img = cv::imdecode(cv::Mat(1, static_cast<int>(size), CV_8UC1, bytes.get()), cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& e) {
    io::failInput(path, 0, std::string("cannot decode image: ") + e.what());
  }
  if (img.empty()) io::failInput(path, 0, "cannot decode image (corrupt or unsupported format)");
  if (img.type() != CV_8UC1) img.convertTo(img, CV_8U);
  return img;
}

}  // namespace linnet
