// YAML options: load / save round trip and every error kind, on a small options tree defined here.
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "io_test_util.h"
#include "linnet/core/options.h"
#include "linnet/io/config_yaml.h"

namespace linnet {
namespace {

struct KltOptions {
  int levels = 3;                  // pyramid levels
  double max_error_px = 1.5;       // forward-backward check, pixels
  Eigen::Vector2i window{21, 21};  // pixels
  template <class V>
  void visit(V& v) {
    v("levels", levels, "pyramid levels", 0, 8);
    v("max_error_px", max_error_px, "forward-backward error, px", 0.0, 100.0);
    v("window", window, "KLT window, px");
  }
};

struct PointOptions {
  int max_points = 150;           // features per frame
  std::string detector = "fast";  // "fast" | "shi_tomasi"
  bool equalize = true;           // CLAHE before tracking
  KltOptions klt;
  template <class V>
  void visit(V& v) {
    v("max_points", max_points, "features per frame", 1, 5000);
    v.choice("detector", detector, "corner detector", {"fast", "shi_tomasi"});
    v("equalize", equalize, "histogram equalisation");
    v.section("klt", klt);
  }
};

struct EstimatorOptions {
  int window_size = 10;                            // keyframes
  double huber_px = 1.0;                           // pixels
  std::vector<double> weights{0.2, 0.8};           // point, line
  std::array<double, 3> gravity{0.0, 0.0, -9.81};  // m/s^2
  Mat3 info = Mat3::Identity();                    // information matrix
  Pose T_B_C;                                      // camera in body
  std::string name = "window";                     // free text
  float scale = 0.1f;                              // unitless
  std::int64_t max_gap_ns = 50'000'000;            // ns
  template <class V>
  void visit(V& v) {
    v("window_size", window_size, "sliding-window keyframes", 2, 50);
    v("huber_px", huber_px, "Huber threshold, px", 0.0, 10.0);
    v("weights", weights, "point, line weights");
    v("gravity", gravity, "m/s^2");
    v("info", info, "information matrix");
    v("T_B_C", T_B_C, "camera in body");
    v("name", name, "free text");
    v("scale", scale, "unitless", 0.0f, 1.0f);
    v("max_gap_ns", max_gap_ns, "ns");
  }
};

struct RootOptions {
  PointOptions points;
  EstimatorOptions estimator;
  double rate_hz = 20.0;  // Hz
  template <class V>
  void visit(V& v) {
    v("rate_hz", rate_hz, "camera rate, Hz", 1.0, 1000.0);
    v.section("points", points);
    v.section("estimator", estimator);
  }
};

std::string errorOf(const std::string& yaml_text) {
  RootOptions o;
  try {
    loadOptions(YAML::Load(yaml_text), o, "config.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(ConfigYaml, MissingKeysKeepDefaultsPresentKeysOverride) {
  RootOptions o;
  loadOptions(
      YAML::Load(
          "points:\n  max_points: 300\n  klt:\n    window: [15, 11]\nestimator:\n  gravity: [0, 0, -9.8]\n"),
      o, "config.yaml");
  EXPECT_EQ(o.points.max_points, 300);
  EXPECT_EQ(o.points.detector, "fast");
  EXPECT_EQ(o.points.klt.levels, 3);
  EXPECT_EQ(o.points.klt.window, Eigen::Vector2i(15, 11));
  EXPECT_EQ(o.estimator.gravity[2], -9.8);
  EXPECT_EQ(o.estimator.window_size, 10);
}

TEST(ConfigYaml, EmptyDocumentChangesNothing) {
  RootOptions o;
  loadOptions(YAML::Load(""), o, "config.yaml");
  EXPECT_EQ(o.points.max_points, 150);
}

TEST(ConfigYaml, PoseFromListAndKalibrMap) {
  RootOptions o;
  loadOptions(YAML::Load("estimator:\n  T_B_C: [0, -1, 0, 1,  1, 0, 0, 2,  0, 0, 1, 3,  0, 0, 0, 1]\n"), o,
              "c.yaml");
  EXPECT_NEAR((o.estimator.T_B_C * Vec3(1, 0, 0) - Vec3(1, 3, 3)).norm(), 0.0, 1e-15);
  RootOptions k;
  loadOptions(YAML::Load("estimator:\n  T_B_C:\n    cols: 4\n    rows: 4\n"
                         "    data: [0, -1, 0, 1,  1, 0, 0, 2,  0, 0, 1, 3,  0, 0, 0, 1]\n"),
              k, "c.yaml");
  EXPECT_NEAR((k.estimator.T_B_C.matrix() - o.estimator.T_B_C.matrix()).norm(), 0.0, 1e-15);
}

TEST(ConfigYaml, SaveLoadRoundTripsExactly) {
  RootOptions o;
  o.rate_hz = 100.0 / 3.0;
  o.points.max_points = 777;
  o.points.detector = "shi_tomasi";
  o.points.equalize = false;
  o.points.klt.max_error_px = 0.1 + 0.2;
  o.points.klt.window = Eigen::Vector2i(9, 7);
  o.estimator.weights = {1e-300, -2.5e17, 0.30000000000000004};
  o.estimator.gravity = {0.1, -0.0, 9.806650000000001};
  o.estimator.info << 1, 2, 3, 4, 5, 6, 7, 8, std::nextafter(9.0, 10.0);
  o.estimator.T_B_C = Pose(expSO3(Vec3(0.3, -0.2, 1.1)), Vec3(0.01, -0.064676986768, 1e-9));
  o.estimator.name = "123";  // looks like a number: must come back as the string
  o.estimator.scale = 0.7f;
  o.estimator.max_gap_ns = 1403715273262142976;

  const io_test::TempDir dir("config_roundtrip");
  const std::string path = (dir / "saved.yaml").string();
  saveOptionsFile(path, o, "Linnet test\nsecond header line");
  RootOptions r;
  r.estimator.weights.clear();
  loadOptionsFile(path, r);
  EXPECT_EQ(r.rate_hz, o.rate_hz);
  EXPECT_EQ(r.points.max_points, 777);
  EXPECT_EQ(r.points.detector, "shi_tomasi");
  EXPECT_FALSE(r.points.equalize);
  EXPECT_EQ(r.points.klt.max_error_px, o.points.klt.max_error_px);
  EXPECT_EQ(r.points.klt.window, o.points.klt.window);
  EXPECT_EQ(r.estimator.weights, o.estimator.weights);
  EXPECT_EQ(r.estimator.gravity, o.estimator.gravity);
  EXPECT_TRUE(std::signbit(r.estimator.gravity[1]));
  EXPECT_EQ(r.estimator.info, o.estimator.info);
  EXPECT_EQ(r.estimator.name, "123");
  EXPECT_EQ(r.estimator.scale, 0.7f);
  EXPECT_EQ(r.estimator.max_gap_ns, 1403715273262142976);
  EXPECT_LT((r.estimator.T_B_C.matrix() - o.estimator.T_B_C.matrix()).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(r.estimator.T_B_C.p, o.estimator.T_B_C.p);

  // The saved text carries the doc strings, ranges and choices as comments, and the header.
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("# Linnet test\n# second header line\n"), std::string::npos) << text;
  EXPECT_NE(text.find("# features per frame [1, 5000]"), std::string::npos) << text;
  EXPECT_NE(text.find("# corner detector {fast | shi_tomasi}"), std::string::npos) << text;
  EXPECT_NE(text.find("\"123\""), std::string::npos) << text;
  // Floats always carry a '.', so YAML 1.1 readers (PyYAML) see floats too.
  EXPECT_NE(text.find("weights: [1.0e-300, -2.5e+17, 0.30000000000000004]"), std::string::npos) << text;
  EXPECT_NE(text.find("huber_px: 1.0  #"), std::string::npos) << text;
  EXPECT_NE(text.find("window: [9, 7]"), std::string::npos) << text;

  // saveOptions() gives the same values as a node; saving the reloaded options gives the same text.
  const YAML::Node node = saveOptions(o);
  EXPECT_EQ(node["points"]["max_points"].as<int>(), 777);
  r.estimator.T_B_C = o.estimator.T_B_C;  // the one field that is not bit-exact (checked above)
  EXPECT_EQ(optionsToYaml(r), optionsToYaml(o));
  EXPECT_NE(optionsToYaml(o).find("scale: 0.7  #"), std::string::npos);
}

TEST(ConfigYaml, OutOfRangeNamesFileLineAndKeyPath) {
  const std::string msg = errorOf("rate_hz: 20\nestimator:\n  huber_px: 1\n  window_size: 0\n");
  EXPECT_EQ(msg, "config.yaml:4: key 'estimator.window_size' = 0 is out of range [2, 50]");
  EXPECT_NE(errorOf("estimator:\n  huber_px: .nan\n").find("out of range [0, 10]"), std::string::npos);
  EXPECT_NE(errorOf("estimator:\n  scale: 1.5\n").find("'estimator.scale' = 1.5 is out of range [0, 1]"),
            std::string::npos);
}

TEST(ConfigYaml, UnknownKeySuggestsClosestName) {
  EXPECT_EQ(errorOf("points:\n  max_pts: 3\n"),
            "config.yaml:2: unknown key 'points.max_pts' (did you mean 'max_points'?)");
  EXPECT_EQ(errorOf("estimatr:\n  window_size: 3\n"),
            "config.yaml:1: unknown key 'estimatr' (did you mean 'estimator'?)");
  const std::string far = errorOf("points:\n  klt:\n    zzzz: 1\n");
  EXPECT_NE(far.find("config.yaml:3: unknown key 'points.klt.zzzz' (known keys in 'points.klt': levels, "
                     "max_error_px, window)"),
            std::string::npos)
      << far;
}

TEST(ConfigYaml, WrongTypesAreReported) {
  EXPECT_EQ(errorOf("points:\n  max_points: ten\n"),
            "config.yaml:2: key 'points.max_points' expects an integer, got 'ten'");
  EXPECT_NE(errorOf("points:\n  max_points: 1.5\n").find("expects an integer, got '1.5'"), std::string::npos);
  EXPECT_NE(errorOf("points:\n  equalize: maybe\n").find("key 'points.equalize' expects true or false"),
            std::string::npos);
  EXPECT_NE(errorOf("rate_hz: [1, 2]\n").find("key 'rate_hz' expects a number, got a list"),
            std::string::npos);
  EXPECT_NE(errorOf("estimator:\n  gravity: [0, 0]\n").find("expects a list of 3 values, got a list of 2"),
            std::string::npos);
  EXPECT_NE(errorOf("estimator:\n  weights: [0.1, x]\n")
                .find("key 'estimator.weights.1' expects a number, got 'x'"),
            std::string::npos);
  EXPECT_NE(
      errorOf("estimator:\n  info: [1, 2, 3]\n").find("expects a 3x3 matrix (9 numbers), got 3 numbers"),
      std::string::npos);
  EXPECT_NE(errorOf("estimator:\n  T_B_C: [2, 0, 0, 0,  0, 1, 0, 0,  0, 0, 1, 0,  0, 0, 0, 1]\n")
                .find("key 'estimator.T_B_C' is not a rigid transform"),
            std::string::npos);
  EXPECT_NE(errorOf("estimator:\n  max_gap_ns: 99999999999999999999\n").find("expects an integer"),
            std::string::npos);
  EXPECT_NE(errorOf("points: 3\n").find("config.yaml:1: key 'points' must be a map of options, got '3'"),
            std::string::npos);
  EXPECT_NE(
      errorOf("points:\n  klt:\n    levels: 100000000000\n").find("does not fit the field's integer type"),
      std::string::npos);
}

TEST(ConfigYaml, BadChoiceListsAllowedValues) {
  EXPECT_EQ(errorOf("points:\n  detector: shi-tomasi\n"),
            "config.yaml:2: key 'points.detector' = 'shi-tomasi' is not one of {fast, shi_tomasi} "
            "(did you mean 'shi_tomasi'?)");
}

TEST(ConfigYaml, DuplicateKeyIsReported) {
  EXPECT_EQ(errorOf("rate_hz: 20\nrate_hz: 30\n"), "config.yaml:2: duplicate key 'rate_hz'");
}

TEST(ConfigYaml, FileErrorsAreInputErrors) {
  RootOptions o;
  const io_test::TempDir dir("config_errors");
  try {
    loadOptionsFile((dir / "missing.yaml").string(), o);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("missing.yaml: file not found"), std::string::npos) << e.what();
  }
  const auto bad = dir / "bad.yaml";
  std::ofstream(bad) << "rate_hz: 20\npoints: [1, 2\nestimator: {}\n";
  try {
    loadOptionsFile(bad.string(), o);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bad.yaml:"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("YAML syntax error"), std::string::npos) << e.what();
  }
  // A ConfigError from a file names the file.
  const auto range = dir / "range.yaml";
  std::ofstream(range) << "# comment\nrate_hz: 0.5\n";
  try {
    loadOptionsFile(range.string(), o);
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()), range.string() + ":2: key 'rate_hz' = 0.5 is out of range [1, 1000]");
  }
}

struct MoreTypes {
  std::vector<bool> flags{true, false};
  std::vector<int> ids{1, 2};
  std::vector<std::string> names{"a", "true", ""};
  Mat3 K = Mat3::Identity();
  unsigned count = 3;
  template <class V>
  void visit(V& v) {
    v("flags", flags, "");
    v("ids", ids, "");
    v("names", names, "");
    v("K", K, "");
    v("count", count, "", 0, 10);  // int bounds on an unsigned field: no sign-compare warning
  }
};

TEST(ConfigYaml, ContainersMatrixFormsAndUnsigned) {
  MoreTypes m;
  loadOptions(YAML::Load("flags: [no, yes, on]\nids: []\nK: [[1, 2, 3], [4, 5, 6], [7, 8, 9]]\n"), m,
              "m.yaml");
  EXPECT_EQ(m.flags, (std::vector<bool>{false, true, true}));
  EXPECT_TRUE(m.ids.empty());
  EXPECT_EQ(m.K(1, 0), 4.0);
  loadOptions(YAML::Load("K: {rows: 3, cols: 3, data: [9, 8, 7, 6, 5, 4, 3, 2, 1]}\n"), m, "m.yaml");
  EXPECT_EQ(m.K(0, 0), 9.0);
  MoreTypes r;
  r.names.clear();
  loadOptions(saveOptions(m), r, "self");
  EXPECT_EQ(r.flags, m.flags);
  EXPECT_EQ(r.names, m.names);  // "true" and "" come back as strings
  EXPECT_EQ(r.K, m.K);
  try {
    loadOptions(YAML::Load("count: -1\n"), m, "m.yaml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("m.yaml:1: key 'count' = -1 does not fit"), std::string::npos)
        << e.what();
  }
  try {
    loadOptions(YAML::Load("K: {rows: 2, cols: 2, data: [1, 2, 3, 4]}\n"), m, "m.yaml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("key 'K' expects a 3x3 matrix, got 2x2"), std::string::npos)
        << e.what();
  }
}

TEST(ConfigYaml, ValidatorAndReaderAgreeOnDefaults) {
  RootOptions o;
  EXPECT_NO_THROW(validateOptions(o));
  EXPECT_NO_THROW(loadOptions(saveOptions(o), o, "self"));
}

}  // namespace
}  // namespace linnet
