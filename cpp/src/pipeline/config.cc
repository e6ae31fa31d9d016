#include "linnet/pipeline/config.h"

#include <fstream>
#include <sstream>

#include <yaml-cpp/yaml.h>

#include "linnet/core/error.h"
#include "linnet/core/options.h"
#include "linnet/io/config_yaml.h"

namespace linnet {

namespace {

Pose poseFromRowMajor(const double (&m)[16]) {
  Mat4 T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = m[4 * r + c];
  return Pose::fromMatrix(T);
}

}  // namespace

Config Config::eurocStereoImu() {
  Config c;
  // EuRoC MAV VI-sensor calibration (mav0/cam0, cam1, imu0 sensor.yaml of every EuRoC sequence).
  c.cam0.model = "pinhole";
  c.cam0.distortion = "radtan";
  c.cam0.width = 752;
  c.cam0.height = 480;
  c.cam0.intrinsics = {458.654, 457.296, 367.215, 248.375};
  c.cam0.distortion_coeffs = {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05};
  const double T_B_C0[16] = {0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,
                             0.999557249008,  0.0149672133247, 0.025715529948,   -0.064676986768,
                             -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,
                             0.0, 0.0, 0.0, 1.0};
  c.cam0.T_B_C = poseFromRowMajor(T_B_C0);
  c.cam0.rate_hz = 20.0;
  c.cam1 = c.cam0;
  c.cam1.intrinsics = {457.587, 456.134, 379.999, 255.238};
  c.cam1.distortion_coeffs = {-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05};
  const double T_B_C1[16] = {0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556,
                             0.999598781151,  0.0130119051815, 0.0251588363115, 0.0453689425024,
                             -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038,
                             0.0, 0.0, 0.0, 1.0};
  c.cam1.T_B_C = poseFromRowMajor(T_B_C1);
  c.stereo = true;
  c.imu = ImuNoise();  // ADIS16448 densities are the ImuNoise defaults
  return c;
}

Config Config::load(const std::string& path) {
  Config c = eurocStereoImu();
  c.merge(path);
  return c;
}

Config Config::fromYaml(const std::string& text, const std::string& source) {
  Config c = eurocStereoImu();
  c.mergeYaml(text, source);
  return c;
}

void Config::merge(const std::string& path) {
  loadOptionsFile(path, *this);
  validate();
}

namespace {

/// A copy of `node` without source marks, so that errors about it name the source but no line.
YAML::Node withoutMarks(const YAML::Node& node) {
  if (node.IsScalar()) return YAML::Node(node.Scalar());
  if (node.IsSequence()) {
    YAML::Node out(YAML::NodeType::Sequence);
    for (const YAML::Node& child : node) out.push_back(withoutMarks(child));
    return out;
  }
  if (node.IsMap()) {
    YAML::Node out(YAML::NodeType::Map);
    for (auto it = node.begin(); it != node.end(); ++it) out[it->first.Scalar()] = withoutMarks(it->second);
    return out;
  }
  return YAML::Node(YAML::NodeType::Null);
}

}  // namespace

void Config::set(const std::string& dotted_key, const std::string& yaml_value, const std::string& source) {
  const std::string where = source.empty() ? dotted_key : source;
  if (dotted_key.empty() || dotted_key.front() == '.' || dotted_key.back() == '.' ||
      dotted_key.find("..") != std::string::npos)
    throw ConfigError(where + ": '" + dotted_key + "' is not a key like 'section.name'");
  YAML::Node value;
  try {
    value = withoutMarks(YAML::Load(yaml_value));
  } catch (const YAML::Exception& e) {
    throw ConfigError(where + ": invalid YAML value '" + yaml_value + "': " + e.msg);
  }
  std::vector<std::string> parts;
  for (std::size_t begin = 0;;) {
    const std::size_t dot = dotted_key.find('.', begin);
    parts.push_back(dotted_key.substr(begin, dot - begin));
    if (dot == std::string::npos) break;
    begin = dot + 1;
  }
  YAML::Node doc = value;
  for (auto it = parts.rbegin(); it != parts.rend(); ++it) {
    YAML::Node parent(YAML::NodeType::Map);
    parent[*it] = doc;
    doc = parent;
  }
  loadOptions(doc, *this, where);
  validate();
}

void Config::mergeYaml(const std::string& text, const std::string& source) {
  YAML::Node node;
  try {
    node = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(source, e.mark.line + 1, std::string("invalid YAML: ") + e.msg);
  }
  loadOptions(node, *this, source);
  validate();
}

void Config::save(const std::string& path) const {
  Config copy = *this;
  saveOptionsFile(path, copy);
}

std::string Config::toYaml(bool comments) const {
  Config copy = *this;
  if (comments) return optionsToYaml(copy, true);
  YAML::Emitter out;
  out << saveOptions(copy);
  return std::string(out.c_str()) + "\n";
}

void Config::validate() const {
  Config copy = *this;
  validateOptions(copy);
  if (cam0.width <= 0 || cam0.height <= 0) throw ConfigError("config key 'cam0.width/height' must be positive");
  if (stereo && (cam1.width != cam0.width || cam1.height != cam0.height))
    throw ConfigError("config keys 'cam1.width/height' must equal cam0's for stereo input");
}

}  // namespace linnet
