"""The sensor module end to end on the loopback interface: emulator -> UDP driver -> System (linnet live), recording,
and exact loss accounting with dropped packets."""
from __future__ import annotations

import shutil
import subprocess
import sys
import threading

import numpy as np
import pytest

MICRO = "euroc/V1_01_easy_micro"
LINNET = [sys.executable, "-m", "linnet.cli"]


def _config(native_size=(752, 480), **sensor):
    import linnet

    cfg = linnet.Config()
    cfg.set("sensor.width", native_size[0])
    cfg.set("sensor.height", native_size[1])
    cfg.set("sensor.idle_timeout_s", 1.0)
    for key, value in sensor.items():
        cfg.set(f"sensor.{key}", value)
    return cfg


def _stream(dataset, live_config, emulate_config, record_dir="", run_system=True, **emulate):
    """Runs run_live in a thread and the emulator in this one; returns (live result, emulator report)."""
    import linnet

    ready = threading.Event()
    port = {}
    result = {}

    def live():
        result.update(linnet._linnet.run_live(live_config, port=0, record_dir=str(record_dir), run_system=run_system,
                                              on_ready=lambda p: (port.update(p=p), ready.set())))

    thread = threading.Thread(target=live)
    thread.start()
    assert ready.wait(10)
    report = linnet._linnet.emulate_dataset(str(dataset), emulate_config, port=port["p"], **emulate)
    thread.join(60)
    assert not thread.is_alive()
    return result, report


def test_live_run_matches_the_run_of_the_recorded_stream(shared_data, tmp_path):
    from linnet.api import load_config

    micro = shared_data(MICRO)
    cfg = load_config(micro)
    for key, value in (("sensor.width", 752), ("sensor.height", 480), ("sensor.idle_timeout_s", 1.0)):
        cfg.set(key, value)
    record = tmp_path / "rec"
    result, report = _stream(micro, cfg, _config(), record_dir=record, rate=1.0)
    counters = result["counters"]
    assert report["packets_dropped"] == 0 and counters["packets"] == report["packets_sent"]
    assert counters["frames_complete"] == 95 and counters["lost_rows_cam0"] + counters["lost_rows_cam1"] == 0
    run = result["summary"]
    assert run.frames == 95 and run.dropped_frames == 0, "the system must keep up at rate 1"
    live = run.trajectory()
    # The recording: images bit for bit; IMU on the folder's stamps, values within half an int16 step.
    import cv2

    for cam in ("cam0", "cam1"):
        names = sorted(p.name for p in (record / "mav0" / cam / "data").iterdir())
        assert len(names) == 95
        for name in names[::10]:
            a = cv2.imread(str(record / "mav0" / cam / "data" / name), cv2.IMREAD_UNCHANGED)
            b = cv2.imread(str(micro / "mav0" / cam / "data" / name), cv2.IMREAD_UNCHANGED)
            assert a.shape == b.shape and (a == b).all()
    rec_imu = np.loadtxt(record / "mav0" / "imu0" / "data.csv", delimiter=",", comments="#")
    src = np.loadtxt(micro / "mav0" / "imu0" / "data.csv", delimiter=",", skiprows=1, max_rows=3000)
    idx = np.searchsorted(src[:, 0], rec_imu[:, 0])
    assert np.array_equal(src[idx, 0], rec_imu[:, 0])
    assert np.abs(src[idx, 4:7] - rec_imu[:, 4:7]).max() <= 0.5 * 2 * 9.80665 / 32768 + 1e-12
    # `linnet run` on the recorded folder (with the calibration added) gives the live trajectory.
    for sub in ("cam0", "cam1", "imu0"):
        shutil.copy(micro / "mav0" / sub / "sensor.yaml", record / "mav0" / sub / "sensor.yaml")
    r = subprocess.run(LINNET + ["run", str(record), "--out", str(tmp_path / "run"), "--quiet"], capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    replay = np.loadtxt(tmp_path / "run" / "trajectory.tum")
    assert np.array_equal(replay[:, 0], live["t_ns"] * 1e-9) or np.allclose(replay[:, 0], live["t_ns"] * 1e-9)
    assert np.abs(replay[:, 1:4] - live["position"]).max() < 1e-6


def test_dropped_packets_are_accounted_exactly(shared_data):
    micro = shared_data(MICRO)
    cfg = _config(incomplete="fill", max_lost_rows_fraction=0.01)
    result, report = _stream(micro, cfg, _config(), run_system=False, rate=4.0, drop_prob=0.002, seed=3)
    c = result["counters"]
    assert report["packets_dropped"] > 50
    assert c["packets"] == report["packets_sent"]
    assert c["lost_rows_cam0"] == report["rows_dropped_cam0"]
    assert c["lost_rows_cam1"] == report["rows_dropped_cam1"]
    assert c["orphan_rows"] == report["rows_of_headless_frames_cam0"] + report["rows_of_headless_frames_cam1"]
    assert c["lost_imu_samples"] == report["imu_dropped"]
    assert c["lost_frame_packets"] == report["frame_packets_dropped"]
    # Every frame whose packet arrived is complete, filled (few lost rows) or dropped by the policy.
    delivered = report["frames"] - report["frame_packets_dropped"]
    assert c["frames_complete"] + c["frames_filled"] + c["frames_dropped"] == delivered
    assert c["frames_filled"] + c["frames_dropped"] == report["frames_with_dropped_rows"]
    kinds = {d["kind"] for d in report["dropped"]}
    assert "row" in kinds and len(report["dropped"]) == report["packets_dropped"]


def test_sensor_cli_errors(tmp_path, shared_data):
    r = subprocess.run(LINNET + ["live", "--udp", "0", "--out", str(tmp_path / "o")], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2 and "no calibration" in r.stderr
    r = subprocess.run(LINNET + ["sensor", "emulate", str(shared_data(MICRO)), "--port", "9", "--host", "nohost"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and "not an IPv4 address" in r.stderr and "Traceback" not in r.stderr


def test_frame_stamp_rule():
    import linnet

    assert linnet._linnet.sensor_frame_stamp([100, 105, 110]) == 105
    assert linnet._linnet.sensor_frame_stamp([100, 106]) == 103
    assert linnet._linnet.sensor_frame_stamp([]) is None


def test_recording_of_module_data_round_trips_bit_for_bit(shared_data, tmp_path):
    """A folder holding the module's own data (int16 IMU values) is recorded back bit for bit: images and IMU csv."""
    micro = shared_data(MICRO)
    first, second = tmp_path / "first", tmp_path / "second"
    _stream(micro, _config(), _config(), record_dir=first, run_system=False, rate=4.0, duration_s=1.0)
    _stream(first, _config(), _config(), record_dir=second, run_system=False, rate=4.0, imu_lead_s=0.0)
    imu1 = (first / "mav0" / "imu0" / "data.csv").read_text().splitlines()
    imu2 = (second / "mav0" / "imu0" / "data.csv").read_text().splitlines()
    assert len(imu2) > 100 and imu2 == imu1[len(imu1) - len(imu2):]  # the second stream starts at the first image
    for cam in ("cam0", "cam1"):
        assert (first / "mav0" / cam / "data.csv").read_text() == (second / "mav0" / cam / "data.csv").read_text()
        for png in (second / "mav0" / cam / "data").iterdir():
            assert png.read_bytes() == (first / "mav0" / cam / "data" / png.name).read_bytes()


def test_sigint_stops_a_live_run_cleanly_with_outputs(shared_data, tmp_path):
    import json
    import signal
    import time

    micro = shared_data(MICRO)
    live = subprocess.Popen(LINNET + ["live", "--udp", "0", "--calib", str(micro), "--out", str(tmp_path / "o"),
                                      "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    port = None
    for _ in range(100):
        line = live.stderr.readline()
        if "listening on udp://" in line:
            port = int(line.rsplit(":", 1)[1])
            break
    assert port is not None
    emulator = subprocess.Popen(LINNET + ["sensor", "emulate", str(micro), "--port", str(port), "--native-size",
                                          "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    time.sleep(3.0)
    live.send_signal(signal.SIGINT)
    out, err = live.communicate(timeout=120)
    emulator.wait(timeout=120)
    assert live.returncode in (0, 3), err
    assert "Traceback" not in err and "ended: stopped" in out
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["end_reason"] == "stopped" and 0 < summary["frames"] < 95
