// Bindings of the sensor-module driver: the emulator (emulate_dataset), live runs and recording (run_live), and the
// protocol's pure functions for tests.
#include <pybind11/functional.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>

#include "bind_callbacks.h"
#include "linnet/driver/live_run.h"
#include "linnet/driver/sensor_emulator.h"

namespace py = pybind11;

namespace linnet::python {

namespace {

/// True once SIGINT (or another signal whose Python handler raises) arrived; the exception is cleared so that the
/// run can stop cleanly and write its outputs.
bool interrupted() {
  py::gil_scoped_acquire gil;
  if (PyErr_CheckSignals() != 0) {
    PyErr_Clear();
    return true;
  }
  return false;
}

py::dict countersDict(const DriverCounters& c) {
  py::dict d;
  d["packets"] = c.packets;
  d["bytes"] = c.bytes;
  d["row_packets"] = c.row_packets;
  d["imu_packets"] = c.imu_packets;
  d["frame_packets"] = c.frame_packets;
  d["bad_packets"] = c.bad_packets;
  d["duplicate_rows"] = c.duplicate_rows;
  d["orphan_rows"] = c.orphan_rows;
  d["lost_rows_cam0"] = c.lost_rows[0];
  d["lost_rows_cam1"] = c.lost_rows[1];
  d["frames_complete"] = c.frames_complete;
  d["frames_filled"] = c.frames_filled;
  d["frames_dropped"] = c.frames_dropped;
  d["frames_without_stamp"] = c.frames_without_stamp;
  d["lost_frame_packets"] = c.lost_frame_packets;
  d["imu_samples"] = c.imu_samples;
  d["lost_imu_samples"] = c.lost_imu_samples;
  d["reordered_imu_samples"] = c.reordered_imu_samples;
  d["ring_overflows"] = c.ring_overflows;
  d["ring_high_water"] = c.ring_high_water;
  d["receive_cpu_s"] = c.receive_cpu_s;
  d["parse_cpu_s"] = c.parse_cpu_s;
  return d;
}

py::dict reportDict(const EmulatorReport& r) {
  py::dict d;
  d["packets_sent"] = r.packets_sent;
  d["bytes_sent"] = r.bytes_sent;
  d["packets_dropped"] = r.packets_dropped;
  d["frames"] = r.frames;
  d["imu_samples_sent"] = r.imu_samples;
  d["imu_dropped"] = r.imu_dropped;
  d["frame_packets_dropped"] = r.frames_dropped;
  d["rows_sent_cam0"] = r.rows_sent[0];
  d["rows_sent_cam1"] = r.rows_sent[1];
  d["rows_dropped_cam0"] = r.rows_dropped[0];
  d["rows_dropped_cam1"] = r.rows_dropped[1];
  d["rows_of_headless_frames_cam0"] = r.rows_of_headless_frames[0];
  d["rows_of_headless_frames_cam1"] = r.rows_of_headless_frames[1];
  d["frames_with_dropped_rows"] = r.frames_with_dropped_rows;
  py::list dropped;
  for (const DroppedPacket& p : r.dropped) {
    py::dict e;
    e["kind"] = p.kind;
    if (p.kind == "imu") {
      e["imu_counter"] = p.imu_counter;
    } else {
      e["frame"] = p.frame;
    }
    if (p.kind == "row") {
      e["camera"] = p.camera;
      e["row"] = p.row;
    }
    dropped.append(e);
  }
  d["dropped"] = dropped;
  d["wall_s"] = r.wall_s;
  d["data_s"] = r.data_s;
  d["late_s"] = r.late_s;
  return d;
}

}  // namespace

void bindDriver(py::module_& m) {
  m.def("emulate_dataset",
        [](const std::string& dataset, const Config& config, const std::string& host, int port, double rate,
           double drop_prob, std::uint64_t seed, double duration_s, double imu_lead_s, int loops,
           std::optional<py::function> progress) {
          EmulatorOptions o;
          o.host = host;
          o.port = port;
          o.rate = rate;
          o.drop_prob = drop_prob;
          o.seed = seed;
          o.duration_s = duration_s;
          o.imu_lead_s = imu_lead_s;
          o.loops = loops;
          const auto cb = withGil<int, int>(progress);
          EmulatorReport report;
          {
            py::gil_scoped_release release;
            report = emulateDataset(dataset, config.sensor, o, cb, interrupted);
          }
          return reportDict(report);
        },
        py::arg("dataset"), py::arg("config"), py::arg("host") = "127.0.0.1", py::arg("port"), py::arg("rate") = 1.0,
        py::arg("drop_prob") = 0.0, py::arg("seed") = 0, py::arg("duration_s") = -1.0, py::arg("imu_lead_s") = 1.0,
        py::arg("loops") = 1, py::arg("progress") = py::none(),
        "Streams a EuRoC folder over UDP as the sensor module would (config.sensor: W, H, IMU ranges); returns what was "
        "sent and dropped. Stops early on Ctrl-C.");

  m.def("run_live",
        [](const Config& config, const std::string& host, int port, double duration_s, const std::string& record_dir,
           bool run_system, std::optional<py::function> on_ready, std::optional<py::function> status) {
          LiveOptions o;
          o.host = host;
          o.port = port;
          o.duration_s = duration_s;
          o.record_dir = record_dir;
          o.run_system = run_system;
          const auto ready = withGil<int>(on_ready);
          std::function<void(const LiveStatus&)> st;
          if (status) {
            auto holder = holdFunction(*status);
            st = [holder](const LiveStatus& s) {
              py::gil_scoped_acquire gil;
              py::dict d;
              d["elapsed_s"] = s.elapsed_s;
              d["frames"] = s.frames;
              d["processed"] = s.processed;
              d["dropped"] = s.dropped;
              d["lost_rows"] = s.lost_rows;
              d["imu_samples"] = s.imu_samples;
              d["tracking"] = s.tracking;
              (*holder)(d);
            };
          }
          LiveResult r;
          {
            py::gil_scoped_release release;
            r = runLive(config, o, ready, interrupted, st);
          }
          py::dict d;
          d["counters"] = countersDict(r.counters);
          d["recorded_frames"] = r.recorded_frames;
          d["recorded_imu"] = r.recorded_imu;
          d["end_reason"] = r.end_reason;
          d["summary"] = run_system && r.summary.frames > 0 ? py::cast(std::move(r.summary)) : py::none();
          return d;
        },
        py::arg("config"), py::arg("host") = "127.0.0.1", py::arg("port") = 0, py::arg("duration_s") = -1.0,
        py::arg("record_dir") = "", py::arg("run_system") = true, py::arg("on_ready") = py::none(),
        py::arg("status") = py::none(),
        "Listens for the sensor module on host:port and runs the System in real-time mode (and / or records the stream "
        "as a EuRoC folder) until duration_s, sensor.idle_timeout_s without packets, or Ctrl-C. Returns a dict: "
        "counters, summary (a RunSummary or None), recorded_frames, recorded_imu, end_reason.");

  m.def("sensor_frame_stamp", [](const std::vector<Timestamp>& stamps) {
        sensor::FramePacket f;
        for (std::size_t i = 0; i < stamps.size(); ++i) f.imu.emplace_back(static_cast<std::uint32_t>(i), stamps[i]);
        return sensor::frameStamp(f);
      }, py::arg("imu_stamps"), "The frame-stamp rule on the exposure's IMU time stamps (None for none)");
}

}  // namespace linnet::python
