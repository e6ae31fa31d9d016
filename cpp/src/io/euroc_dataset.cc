#include "linnet/io/euroc_dataset.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string_view>
#include <unordered_set>

#include <opencv2/imgcodecs.hpp>

#include "linnet/core/error.h"
#include "linnet/io/config_yaml.h"
#include "linnet/io/text_parse.h"
#include "linnet/io/yaml_values.h"

namespace linnet {
namespace fs = std::filesystem;
namespace {

/// A required key of a sensor.yaml, or InputError "<file>: missing key '<key>'".
YAML::Node requireKey(const YAML::Node& root, const std::string& file, const char* key) {
  const YAML::Node n = root[key];
  if (!n) io::failInput(file, 0, std::string("missing key '") + key + "'");
  return n;
}

YAML::Node loadSensorYaml(const std::string& path) {
  const YAML::Node root = loadYamlFile(path);
  if (!root.IsMap())
    io::failInput(path, 0, "expected a map of sensor parameters, got " + yaml::describe(root));
  return root;
}

template <class T>
T readValue(const YAML::Node& root, const std::string& file, const char* key) {
  T value{};
  yaml::decode(requireKey(root, file, key), yaml::Context{file, key, true}, value);
  return value;
}

double readPositive(const YAML::Node& root, const std::string& file, const char* key) {
  const double v = readValue<double>(root, file, key);
  if (!(v > 0.0) || !std::isfinite(v))
    yaml::Context{file, key, true}.fail(root[key], "must be a positive number, got " + io::formatDouble(v));
  return v;
}

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
};

CameraStream readCameraStream(const fs::path& cam_dir, bool check_images, int threads) {
  CameraStream s;
  const fs::path csv = cam_dir / "data.csv";
  s.calib = readCameraSensorYaml((cam_dir / "sensor.yaml").string());
  s.rows = readCameraCsv(csv.string(), threads);
  s.data_dir = cam_dir / "data";
  if (check_images) {
    std::error_code ec;
    if (!fs::is_directory(s.data_dir, ec))
      io::failInput(s.data_dir.string(), 0, "image folder not found (listed by " + csv.string() + ")");
    const std::unordered_set<std::string> names = listFileNames(s.data_dir);
    for (const CameraCsvRow& r : s.rows) {
      const bool plain = r.filename.find('/') == std::string::npos;
      const bool found = plain ? names.count(r.filename) > 0 : fs::exists(s.data_dir / r.filename, ec);
      if (!found)
        io::failInput(csv.string(), r.line, "image not found on disk: " + (s.data_dir / r.filename).string());
    }
  }
  return s;
}

}  // namespace

CameraCalibration readCameraSensorYaml(const std::string& path) {
  const YAML::Node root = loadSensorYaml(path);
  CameraCalibration c;
  yaml::decode(requireKey(root, path, "T_BS"), yaml::Context{path, "T_BS", true}, c.T_B_C);
  c.rate_hz = readPositive(root, path, "rate_hz");
  const auto res = readValue<std::array<int, 2>>(root, path, "resolution");
  if (res[0] <= 0 || res[1] <= 0)
    yaml::Context{path, "resolution", true}.fail(root["resolution"],
                                                 "must be two positive integers [width, height]");
  c.width = res[0];
  c.height = res[1];
  c.model = readValue<std::string>(root, path, "camera_model");
  if (c.model != "pinhole")
    yaml::Context{path, "camera_model", true}.fail(root["camera_model"],
                                                   "= '" + c.model + "' is not supported (pinhole)");
  c.intrinsics = readValue<std::array<double, 4>>(root, path, "intrinsics");
  for (int i = 0; i < 4; ++i) {
    const double x = c.intrinsics[static_cast<std::size_t>(i)];
    if (!std::isfinite(x) || (i < 2 && x <= 0.0))
      yaml::Context{path, "intrinsics", true}.fail(root["intrinsics"],
                                                   "must be [fx, fy, cx, cy] with fx, fy > 0");
  }
  const std::string dist = readValue<std::string>(root, path, "distortion_model");
  std::size_t expected = 4;
  if (dist == "radial-tangential" || dist == "radtan" || dist == "plumb_bob") {
    c.distortion = "radtan";
  } else if (dist == "equidistant" || dist == "fisheye" || dist == "kannala_brandt" || dist == "kb4") {
    c.distortion = "equidistant";
  } else if (dist == "none") {
    c.distortion = "none";
    expected = 0;
  } else {
    yaml::Context{path, "distortion_model", true}.fail(
        root["distortion_model"],
        "= '" + dist + "' is not supported (radial-tangential | radtan | equidistant | none)");
  }
  c.distortion_coeffs = expected == 0 && !root["distortion_coefficients"]
                            ? std::vector<double>{}
                            : readValue<std::vector<double>>(root, path, "distortion_coefficients");
  if (c.distortion_coeffs.size() != expected)
    yaml::Context{path, "distortion_coefficients", true}.fail(
        root["distortion_coefficients"], "must hold " + std::to_string(expected) + " values for '" + dist +
                                             "', got " + std::to_string(c.distortion_coeffs.size()));
  return c;
}

ImuNoise readImuSensorYaml(const std::string& path, Pose* T_B_S) {
  const YAML::Node root = loadSensorYaml(path);
  ImuNoise n;
  n.gyr_noise_density = readPositive(root, path, "gyroscope_noise_density");
  n.gyr_random_walk = readPositive(root, path, "gyroscope_random_walk");
  n.acc_noise_density = readPositive(root, path, "accelerometer_noise_density");
  n.acc_random_walk = readPositive(root, path, "accelerometer_random_walk");
  n.rate_hz = readPositive(root, path, "rate_hz");
  if (T_B_S) {
    *T_B_S = Pose();
    if (const YAML::Node t = root["T_BS"]) yaml::decode(t, yaml::Context{path, "T_BS", true}, *T_B_S);
  }
  return n;
}

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
  d.imu_noise_ = readImuSensorYaml((mav0 / "imu0" / "sensor.yaml").string(), &T_B_I);
  d.imu_ = readImuCsv((mav0 / "imu0" / "data.csv").string(), options.threads);
  if (d.imu_.empty()) io::failInput((mav0 / "imu0" / "data.csv").string(), 0, "no IMU samples");
  const Pose T_I_B = T_B_I.inverse();
  if (!isIdentity(T_B_I))
    d.warnings_.push_back("imu0 T_BS is not the identity: camera extrinsics re-expressed in the IMU frame");
  const auto gaps = [&] {
    std::size_t count = 0;
    const double max_dt_ns = 3.0e9 / d.imu_noise_.rate_hz;
    for (std::size_t i = 1; i < d.imu_.size(); ++i)
      if (static_cast<double>(d.imu_[i].t - d.imu_[i - 1].t) > max_dt_ns) ++count;
    return count;
  }();
  if (gaps > 0) d.warnings_.push_back("imu0: " + std::to_string(gaps) + " gaps longer than 3 sample periods");

  CameraStream cam0 = readCameraStream(mav0 / "cam0", options.check_images, options.threads);
  d.cam0_ = cam0.calib;
  d.cam0_.T_B_C = T_I_B * d.cam0_.T_B_C;
  if (cam0.rows.empty()) io::failInput((mav0 / "cam0" / "data.csv").string(), 0, "no images listed");

  const bool want_cam1 = options.use_cam1 && fs::is_directory(mav0 / "cam1", ec);
  if (!want_cam1) {
    d.frames_.reserve(cam0.rows.size());
    for (const auto& r : cam0.rows) d.frames_.push_back({r.t, (cam0.data_dir / r.filename).string(), ""});
  } else {
    CameraStream cam1 = readCameraStream(mav0 / "cam1", options.check_images, options.threads);
    d.cam1_ = cam1.calib;
    d.cam1_.T_B_C = T_I_B * d.cam1_.T_B_C;
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
  if (d.frames_.front().t < d.imu_.front().t || d.frames_.back().t > d.imu_.back().t)
    d.warnings_.push_back("images extend beyond the IMU log (first/last image outside the IMU time span)");

  const fs::path gt_dir = mav0 / "state_groundtruth_estimate0";
  if (options.load_ground_truth && fs::exists(gt_dir / "data.csv", ec)) {
    d.ground_truth_ = readEurocCsv((gt_dir / "data.csv").string(), options.threads);
    Pose T_B_S;
    if (fs::exists(gt_dir / "sensor.yaml", ec)) {
      const std::string gt_yaml = (gt_dir / "sensor.yaml").string();
      const YAML::Node root = loadSensorYaml(gt_yaml);
      if (const YAML::Node t = root["T_BS"]) yaml::decode(t, yaml::Context{gt_yaml, "T_BS", true}, T_B_S);
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
  cv::Mat img;
  try {
    img = cv::imread(path, cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& e) {
    io::failInput(path, 0, std::string("cannot decode image: ") + e.what());
  }
  if (img.empty()) io::failInput(path, 0, "cannot decode image (corrupt or unsupported format)");
  if (img.type() != CV_8UC1) img.convertTo(img, CV_8U);
  return img;
}

}  // namespace linnet
