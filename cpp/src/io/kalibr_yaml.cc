#include "linnet/io/kalibr_yaml.h"

#include <array>
#include <cmath>

#include "linnet/core/error.h"
#include "linnet/io/config_yaml.h"
#include "linnet/io/text_parse.h"
#include "linnet/io/yaml_values.h"

namespace linnet {
namespace {

/// The keys of one YAML map of a calibration file, read strictly (InputError naming file, line, key path).
class SensorMap {
 public:
  SensorMap(const YAML::Node& node, std::string file, std::string prefix)
      : node_(node), file_(std::move(file)), prefix_(std::move(prefix)) {
    if (!node_.IsMap())
      io::failInput(file_, node_.IsDefined() ? node_.Mark().line + 1 : 0,
                    (prefix_.empty() ? std::string("expected a map of sensor parameters")
                                     : "key '" + prefix_ + "' must be a map") +
                        ", got " + yaml::describe(node_));
  }

  bool has(const char* key) const { return static_cast<bool>(node_[key]); }
  YAML::Node node(const char* key) const { return node_[key]; }
  yaml::Context context(const char* key) const { return {file_, path(key), true}; }

  YAML::Node require(const char* key) const {
    const YAML::Node n = node_[key];
    if (!n)
      io::failInput(file_, prefix_.empty() ? 0 : node_.Mark().line + 1, "missing key '" + path(key) + "'");
    return n;
  }
  template <class T>
  T get(const char* key) const {
    T value{};
    yaml::decode(require(key), context(key), value);
    return value;
  }
  double positive(const char* key) const {
    const double v = get<double>(key);
    if (!(v > 0.0) || !std::isfinite(v))
      context(key).fail(node_[key], "must be a positive number, got " + io::formatDouble(v));
    return v;
  }
  /// The first of `keys` that is present (for files that spell a key in two ways), or fail naming the first.
  const char* firstOf(std::initializer_list<const char*> keys) const {
    for (const char* k : keys)
      if (has(k)) return k;
    require(*keys.begin());
    return *keys.begin();
  }

 private:
  std::string path(const char* key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  YAML::Node node_;
  std::string file_, prefix_;
};

YAML::Node loadRoot(const std::string& path) {
  const YAML::Node root = loadYamlFile(path);
  SensorMap check(root, path, "");
  return root;
}

/// The intrinsic part shared by EuRoC sensor.yaml and Kalibr camchain entries.
void readIntrinsics(const SensorMap& m, CameraCalibration* c) {
  const auto res = m.get<std::array<int, 2>>("resolution");
  if (res[0] <= 0 || res[1] <= 0)
    m.context("resolution").fail(m.node("resolution"), "must be two positive integers [width, height]");
  c->width = res[0];
  c->height = res[1];
  c->model = m.get<std::string>("camera_model");
  if (c->model != "pinhole")
    m.context("camera_model").fail(m.node("camera_model"), "= '" + c->model + "' is not supported (pinhole)");
  c->intrinsics = m.get<std::array<double, 4>>("intrinsics");
  for (std::size_t i = 0; i < 4; ++i) {
    const double x = c->intrinsics[i];
    if (!std::isfinite(x) || (i < 2 && x <= 0.0))
      m.context("intrinsics").fail(m.node("intrinsics"), "must be [fx, fy, cx, cy] with fx, fy > 0");
  }
  const std::string dist = m.get<std::string>("distortion_model");
  std::size_t expected = 4;
  if (dist == "radial-tangential" || dist == "radtan" || dist == "plumb_bob") {
    c->distortion = "radtan";
  } else if (dist == "equidistant" || dist == "fisheye" || dist == "kannala_brandt") {
    c->distortion = "equidistant";
  } else if (dist == "none") {
    c->distortion = "none";
    expected = 0;
  } else {
    m.context("distortion_model")
        .fail(m.node("distortion_model"),
              "= '" + dist + "' is not supported (radial-tangential | radtan | equidistant | none)");
  }
  const bool any_coeffs = m.has("distortion_coefficients") || m.has("distortion_coeffs");
  if (expected == 0 && !any_coeffs) {
    c->distortion_coeffs.clear();
    return;
  }
  const char* key = m.firstOf({"distortion_coefficients", "distortion_coeffs"});
  c->distortion_coeffs = m.get<std::vector<double>>(key);
  // radtan also takes k3 (OpenCV's order: k1 k2 p1 p2 k3).
  const bool ok = c->distortion_coeffs.size() == expected ||
                  (c->distortion == "radtan" && c->distortion_coeffs.size() == 5);
  if (!ok) {
    const std::string counts = c->distortion == "radtan" ? "4 or 5" : std::to_string(expected);
    m.context(key).fail(m.node(key), "must hold " + counts + " values for '" + dist + "', got " +
                                         std::to_string(c->distortion_coeffs.size()));
  }
}

}  // namespace

CameraCalibration readCameraSensorYaml(const std::string& path) {
  const SensorMap m(loadRoot(path), path, "");
  CameraCalibration c;
  c.T_B_C = m.get<Pose>("T_BS");
  c.rate_hz = m.positive("rate_hz");
  readIntrinsics(m, &c);
  return c;
}

ImuNoise readImuSensorYaml(const std::string& path, Pose* T_B_S) {
  const YAML::Node root = loadRoot(path);
  // Kalibr imu.yaml nests everything under imu0:, EuRoC's sensor.yaml does not.
  const bool nested = root["imu0"] && root["imu0"].IsMap();
  const SensorMap m(nested ? root["imu0"] : root, path, nested ? "imu0" : "");
  ImuNoise n;
  n.gyr_noise_density = m.positive("gyroscope_noise_density");
  n.gyr_random_walk = m.positive("gyroscope_random_walk");
  n.acc_noise_density = m.positive("accelerometer_noise_density");
  n.acc_random_walk = m.positive("accelerometer_random_walk");
  n.rate_hz = m.positive(m.firstOf({"rate_hz", "update_rate"}));
  if (T_B_S) {
    *T_B_S = Pose();
    if (m.has("T_BS"))
      *T_B_S = m.get<Pose>("T_BS");
    else if (m.has("T_i_b"))
      *T_B_S = m.get<Pose>("T_i_b").inverse();  // Kalibr: body -> IMU
  }
  return n;
}

KalibrCamchain readKalibrCamchain(const std::string& path) {
  const YAML::Node root = loadRoot(path);
  KalibrCamchain chain;
  for (int i = 0;; ++i) {
    const std::string name = "cam" + std::to_string(i);
    const YAML::Node node = root[name];
    if (!node) break;
    const SensorMap m(node, path, name);
    CameraCalibration c;
    readIntrinsics(m, &c);
    if (m.has("T_cam_imu")) {
      c.T_B_C = m.get<Pose>("T_cam_imu").inverse();
    } else if (i > 0 && m.has("T_cn_cnm1")) {
      // T_cn_cnm1 maps camera i-1 coordinates to camera i: T_B_Ci = T_B_Ci-1 * T_cn_cnm1^-1.
      c.T_B_C = chain.cameras.back().T_B_C * m.get<Pose>("T_cn_cnm1").inverse();
    } else {
      m.require("T_cam_imu");
    }
    chain.timeshift_cam_imu_s.push_back(m.has("timeshift_cam_imu") ? m.get<double>("timeshift_cam_imu")
                                                                   : 0.0);
    chain.cameras.push_back(c);
  }
  if (chain.cameras.empty()) io::failInput(path, 0, "missing key 'cam0' (not a Kalibr camchain)");
  return chain;
}

}  // namespace linnet
