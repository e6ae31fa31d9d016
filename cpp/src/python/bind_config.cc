// Bindings of Config: defaults, YAML in and out, calibrations from a EuRoC folder or Kalibr files, single keys.
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "linnet/pipeline/config.h"
#include "linnet/pipeline/dataset_runner.h"

namespace py = pybind11;

namespace linnet::python {

namespace {

EurocOpenOptions calibrationFiles(const std::string& camchain, const std::string& imu_yaml) {
  EurocOpenOptions o;
  o.camchain = camchain;
  o.imu_yaml = imu_yaml;
  return o;
}

/// A Python value as YAML text (flow style, one line), through PyYAML.
std::string toYamlText(const py::object& value) {
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  py::object yaml = py::module_::import("yaml");
  return yaml.attr("safe_dump")(value, py::arg("default_flow_style") = true).cast<std::string>();
}

}  // namespace

void bindConfig(py::module_& m) {
  py::class_<Config>(m, "Config", "Root configuration (one options section per module); YAML in and out.")
      .def(py::init([] { return Config::eurocStereoImu(); }))
      .def_static("euroc_stereo_imu", &Config::eurocStereoImu, "EuRoC stereo-inertial defaults")
      .def_static("load", &Config::load, py::arg("path"), "Defaults overridden by a YAML file")
      .def_static("from_yaml", &Config::fromYaml, py::arg("text"), py::arg("source") = "<yaml>")
      .def_static("for_euroc", [](const std::string& dataset, const Config* base, const std::string& camchain,
                                  const std::string& imu_yaml) {
            return configForEuroc(dataset, base ? *base : Config::eurocStereoImu(),
                                  calibrationFiles(camchain, imu_yaml));
          }, py::arg("dataset"), py::arg("base") = nullptr, py::arg("camchain") = "", py::arg("imu_yaml") = "",
          "Config with the calibration (cameras, IMU noise) of a EuRoC folder: its sensor.yaml files, or a Kalibr "
          "camchain / imu.yaml given here. Monocular when the folder (or camchain) has one camera.")
      .def_static("for_kalibr", [](const std::string& camchain, const std::string& imu_yaml, double rate_hz,
                                   const Config* base) {
            return configForKalibr(camchain, imu_yaml, rate_hz, base ? *base : Config::eurocStereoImu());
          }, py::arg("camchain"), py::arg("imu_yaml") = "", py::arg("rate_hz") = 20.0, py::arg("base") = nullptr,
          "Config with the cameras of a Kalibr camchain (rate_hz: camera frame rate, Hz; camchains do not hold it) "
          "and the IMU noise of a Kalibr imu.yaml (empty: the defaults')")
      .def("merge", &Config::merge, py::arg("path"), "Overrides the keys present in a YAML file")
      .def("merge_yaml", &Config::mergeYaml, py::arg("text"), py::arg("source") = "<yaml>")
      .def("set", [](Config& c, const std::string& key, const py::object& value, const std::string& source) {
            c.set(key, toYamlText(value), source);
          }, py::arg("key"), py::arg("value"), py::arg("source") = "",
          "Sets one key, e.g. cfg.set(\"pipeline.use_lines\", False); a str value is parsed as YAML. ConfigError "
          "naming the key (or `source`) when unknown or out of range.")
      .def("save", &Config::save, py::arg("path"))
      .def("to_yaml", &Config::toYaml, py::arg("comments") = false,
           "Every key as YAML; comments=True adds each key's documentation and range")
      .def("validate", &Config::validate)
      .def_property("stereo", [](const Config& c) { return c.stereo; }, [](Config& c, bool s) { c.stereo = s; })
      .def_property("blocking", [](const Config& c) { return c.pipeline.blocking; },
                    [](Config& c, bool b) { c.pipeline.blocking = b; })
      .def_property("use_lines", [](const Config& c) { return c.pipeline.use_lines; },
                    [](Config& c, bool b) { c.pipeline.use_lines = b; })
      .def_property_readonly("camera_rate_hz", [](const Config& c) { return c.cam0.rate_hz; })
      .def("__repr__", [](const Config& c) {
        return "<linnet.Config stereo=" + std::string(c.stereo ? "True" : "False") + ">";
      });
}

}  // namespace linnet::python
