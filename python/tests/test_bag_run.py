"""`linnet run BAG`: ROS1 and ROS2 bags written from a EuRoC folder run to the same trajectory as the folder, with the
folder's calibration or with the same calibration as Kalibr files."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

LINNET = [sys.executable, "-m", "linnet.cli"]
MICRO = "euroc/V1_01_easy_micro"
FRAMES = 40


def _run(*args):
    return subprocess.run(LINNET + [str(a) for a in args], capture_output=True, text=True, timeout=600)


def _opencv_yaml(path):
    text = path.read_text()
    return yaml.safe_load(text.split("\n", 1)[1] if text.startswith("%YAML") else text)


def _kalibr_files(euroc, out):
    """The EuRoC folder's calibration as a Kalibr camchain (T_cam_imu = T_B_C^-1, B = IMU) and imu.yaml."""
    chain = {}
    for i in (0, 1):
        s = _opencv_yaml(euroc / "mav0" / f"cam{i}" / "sensor.yaml")
        T_B_C = np.array(s["T_BS"]["data"], float).reshape(4, 4)
        chain[f"cam{i}"] = {
            "T_cam_imu": np.linalg.inv(T_B_C).tolist(),
            "camera_model": "pinhole",
            "intrinsics": s["intrinsics"],
            "distortion_model": "radtan",
            "distortion_coeffs": s["distortion_coefficients"],
            "resolution": s["resolution"],
            "rostopic": f"/cam{i}/image_raw",
        }
    imu = {k: v for k, v in _opencv_yaml(euroc / "mav0" / "imu0" / "sensor.yaml").items()
           if k.endswith(("noise_density", "random_walk"))}
    imu.update(rostopic="/imu0", update_rate=200.0)
    (out / "camchain.yaml").write_text(yaml.safe_dump(chain))
    (out / "imu.yaml").write_text(yaml.safe_dump({"imu0": imu}))
    return out / "camchain.yaml", out / "imu.yaml"


@pytest.fixture(scope="module")
def folder_run(tmp_path_factory, shared_data_module):
    euroc = shared_data_module(MICRO)
    out = tmp_path_factory.mktemp("folder")
    r = _run("run", euroc, "--out", out / "run", "--quiet", "--max-frames", FRAMES)
    assert r.returncode == 0, r.stderr
    return euroc, (out / "run" / "trajectory.tum").read_text()


@pytest.fixture(scope="module")
def shared_data_module():
    from conftest import require_shared_data

    return require_shared_data


@pytest.mark.parametrize("version, storage", [(1, "sqlite3"), (2, "sqlite3"), (2, "mcap")])
def test_bag_runs_to_the_folder_trajectory(tmp_path, folder_run, version, storage):
    from linnet.bags import write_bag_from_euroc

    euroc, expected = folder_run
    bag = write_bag_from_euroc(euroc, tmp_path / ("b.bag" if version == 1 else "b2"), version=version,
                               max_frames=FRAMES, storage=storage)
    r = _run("run", bag, "--calib", euroc, "--out", tmp_path / "run", "--quiet")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "run" / "trajectory.tum").read_text() == expected


def test_bag_with_kalibr_calibration(tmp_path, folder_run):
    from linnet.bags import write_bag_from_euroc

    euroc, expected = folder_run
    bag = write_bag_from_euroc(euroc, tmp_path / "b.bag", version=1, max_frames=FRAMES)
    camchain, imu = _kalibr_files(euroc, tmp_path)
    r = _run("run", bag, "--calib", camchain, "--calib", imu, "--out", tmp_path / "run", "--quiet")
    assert r.returncode == 0, r.stderr
    got = np.loadtxt(tmp_path / "run" / "trajectory.tum")
    ref = np.loadtxt(expected.splitlines())
    assert got.shape == ref.shape and np.max(np.abs(got[:, 1:4] - ref[:, 1:4])) < 1e-6


def test_folder_with_kalibr_calibration_matches_sensor_yaml(tmp_path, folder_run):
    euroc, expected = folder_run
    camchain, imu = _kalibr_files(euroc, tmp_path)
    r = _run("run", euroc, "--calib", camchain, "--calib", imu, "--out", tmp_path / "run", "--quiet",
             "--max-frames", FRAMES)
    assert r.returncode == 0, r.stderr
    got = np.loadtxt(tmp_path / "run" / "trajectory.tum")
    ref = np.loadtxt(expected.splitlines())
    assert got.shape == ref.shape and np.max(np.abs(got[:, 1:4] - ref[:, 1:4])) < 1e-6


def test_bag_errors(tmp_path, folder_run):
    from linnet.bags import write_bag_from_euroc

    euroc, _ = folder_run
    bag = write_bag_from_euroc(euroc, tmp_path / "b.bag", version=1, max_frames=5)
    r = _run("run", bag, "--out", tmp_path / "o")
    assert r.returncode == 2 and "holds no calibration" in r.stderr
    r = _run("run", bag, "--calib", euroc, "--imu-topic", "/imu9", "--out", tmp_path / "o")
    assert r.returncode == 1 and "/imu9" in r.stderr and "/imu0" in r.stderr and "Traceback" not in r.stderr
    not_a_bag = tmp_path / "x.bag"
    not_a_bag.write_text("hello")
    r = _run("run", not_a_bag, "--calib", euroc, "--out", tmp_path / "o")
    assert r.returncode == 1 and "x.bag" in r.stderr and "Traceback" not in r.stderr


def test_realtime_replay_paces_and_reports_drops(tmp_path, folder_run):
    euroc, _ = folder_run
    r = _run("run", euroc, "--out", tmp_path / "run", "--quiet", "--max-frames", 20, "--realtime", "4")
    assert r.returncode == 0, r.stderr
    import json

    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    duration = summary["sequence_duration_s"]
    assert summary["wall_time_s"] >= 0.9 * (duration - 0.05) / 4.0
    assert summary["frames"] == 20 and summary["processed_frames"] + summary["dropped_frames"] >= 20


def test_config_file_calibration_replaces_sensor_yaml(tmp_path, folder_run):
    """A folder without sensor.yaml files (as TUM-VI's) runs with the calibration of a config file."""
    import shutil

    euroc, expected = folder_run
    config = tmp_path / "calib.yaml"
    assert _run("config", "--dataset", euroc, "--out", config).returncode == 0
    bare = tmp_path / "bare" / "mav0"
    for sub in ("cam0", "cam1", "imu0"):
        (bare / sub).mkdir(parents=True)
        shutil.copy(euroc / "mav0" / sub / "data.csv", bare / sub / "data.csv")
        if sub != "imu0":
            (bare / sub / "data").symlink_to(euroc / "mav0" / sub / "data")
    r = _run("run", bare.parent, "--out", tmp_path / "plain", "--quiet", "--max-frames", FRAMES)
    assert r.returncode == 1 and "sensor.yaml" in r.stderr
    # TUM-VI keeps its ground truth in mav0/mocap0 (t, p, q wxyz): summary.json gets the APE from it.
    (bare / "mocap0").mkdir()
    gt_rows = (euroc / "mav0" / "state_groundtruth_estimate0" / "data.csv").read_text().splitlines()
    (bare / "mocap0" / "data.csv").write_text("\n".join(",".join(r.split(",")[:8]) for r in gt_rows) + "\n")
    r = _run("run", bare.parent, "--config", config, "--out", tmp_path / "run", "--quiet", "--max-frames", FRAMES)
    assert r.returncode == 0, r.stderr
    import json

    assert json.loads((tmp_path / "run" / "summary.json").read_text())["ape"]["rmse_m"] < 0.01
    got = np.loadtxt(tmp_path / "run" / "trajectory.tum")  # equal up to the config file's decimal round trip
    ref = np.loadtxt(expected.splitlines())
    assert got.shape == ref.shape and np.max(np.abs(got - ref)) < 1e-9


def test_shipped_tumvi_config():
    from pathlib import Path

    import linnet

    cfg = linnet.Config.load(str(Path(__file__).resolve().parents[2] / "config" / "tumvi_stereo_imu.yaml"))
    text = cfg.to_yaml()
    assert cfg.stereo and "distortion: equidistant" in text and "width: 512" in text
    assert "acc_noise_density: 0.0028" in text


def test_bag_with_an_imu_gap_hands_every_frame_over(tmp_path, folder_run):
    """Frames inside an IMU gap reach the System (it reports them), as from the folder."""
    import shutil

    from linnet.bags import write_bag_from_euroc

    euroc, _ = folder_run
    gap = tmp_path / "gap"
    for sub in ("cam0", "cam1", "imu0"):
        (gap / "mav0" / sub).mkdir(parents=True)
        shutil.copy(euroc / "mav0" / sub / "sensor.yaml", gap / "mav0" / sub / "sensor.yaml")
        shutil.copy(euroc / "mav0" / sub / "data.csv", gap / "mav0" / sub / "data.csv")
        if sub != "imu0":
            (gap / "mav0" / sub / "data").symlink_to(euroc / "mav0" / sub / "data")
    frames = (gap / "mav0" / "cam0" / "data.csv").read_text().splitlines()[1:]
    t0, t1 = int(frames[20].split(",")[0]) - 1, int(frames[24].split(",")[0]) + 1  # 4 frame periods without IMU
    imu = gap / "mav0" / "imu0" / "data.csv"
    rows = imu.read_text().splitlines()
    imu.write_text("\n".join([rows[0]] + [r for r in rows[1:] if not t0 < int(r.split(",")[0]) < t1]) + "\n")
    bag = write_bag_from_euroc(gap, tmp_path / "g.bag", version=1, max_frames=FRAMES)
    r_bag = _run("run", bag, "--calib", gap, "--out", tmp_path / "rb", "--quiet")
    r_dir = _run("run", gap, "--out", tmp_path / "rd", "--quiet", "--max-frames", FRAMES)
    assert r_bag.returncode == 0 and r_dir.returncode == 0, (r_bag.stderr, r_dir.stderr)
    import json

    sb = json.loads((tmp_path / "rb" / "summary.json").read_text())
    sd = json.loads((tmp_path / "rd" / "summary.json").read_text())
    assert sb["frames"] == sd["frames"] == FRAMES
    assert (tmp_path / "rb" / "trajectory.tum").read_text() == (tmp_path / "rd" / "trajectory.tum").read_text()
