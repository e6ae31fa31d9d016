"""The Python API: Config, System on numpy arrays, errors."""
import numpy as np
import pytest

import linnet


def test_config_round_trips_through_yaml(tmp_path):
    # The extrinsics pass through a quaternion once; from then on save -> load is exact.
    cfg = linnet.Config.from_yaml(linnet.Config.euroc_stereo_imu().to_yaml())
    text = cfg.to_yaml()
    assert "estimator:" in text and "points:" in text
    again = linnet.Config.from_yaml(text)
    assert again.to_yaml() == text
    path = tmp_path / "c.yaml"
    cfg.save(str(path))
    assert linnet.Config.load(str(path)).to_yaml() == text


def test_config_errors_name_the_key(tmp_path):
    with pytest.raises(linnet.ConfigError, match="estimator.window_size"):
        linnet.Config.from_yaml("estimator:\n  window_size: 0\n")
    with pytest.raises(linnet.ConfigError, match="no_such_key"):
        linnet.Config.from_yaml("points:\n  no_such_key: 3\n")


def test_system_rejects_bad_input():
    cfg = linnet.Config.euroc_stereo_imu()
    system = linnet.System(cfg)
    system.add_imu(1000, np.array([0.0, 0.0, 9.81]), np.zeros(3))
    with pytest.raises(linnet.UsageError, match="increase"):
        system.add_imu(1000, np.array([0.0, 0.0, 9.81]), np.zeros(3))
    with pytest.raises(linnet.UsageError, match="752x480|calibration"):
        system.add_stereo(2000, np.zeros((10, 10), np.uint8), np.zeros((10, 10), np.uint8))
    with pytest.raises(linnet.UsageError):
        system.add_mono(2000, np.zeros((480, 752), np.uint8))
    system.finish()


def test_system_runs_on_arrays_and_calls_back():
    cfg = linnet.Config.euroc_stereo_imu()
    system = linnet.System(cfg)
    seen, calibration = [], []
    system.set_callback(lambda r: (seen.append(r.t_ns), calibration.append((r.time_offset_s, r.extrinsics_correction))))
    rng = np.random.default_rng(0)
    image = (rng.random((480, 752)) * 255).astype(np.uint8)
    t = 0
    for k in range(10):
        for _ in range(10):
            t += 5_000_000
            system.add_imu(t, np.array([0.0, 0.0, 9.81]), np.zeros(3))
        system.add_stereo(t, image, image)
    for _ in range(3):
        t += 5_000_000
        system.add_imu(t, np.array([0.0, 0.0, 9.81]), np.zeros(3))
    system.finish()
    assert len(seen) == 10
    # Online calibration as each frame reports it: the offset starts at estimator.time_offset.initial_ms (0), the
    # extrinsics correction is the identity unless estimated.
    assert all(td == 0.0 and np.array_equal(T, np.eye(4)) for td, T in calibration)
    traj = system.trajectory(only_with_pose=False)
    assert traj["t_ns"].shape == (10,)
