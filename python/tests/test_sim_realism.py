"""Tests of the simulator's realism (issue 11): the measured IMU noise model (PSD fit, synthesis, the shipped model),
calibration errors written and read back, camera clock offset and jitter, the ``--realism`` preset."""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from linnet.sim import InputError, builtin_loop
from linnet.sim import imu_model as M
from linnet.sim.imu import ImuNoise, synthesize
from linnet.sim.realism import CalibrationErrorAmounts, camera_stamps, perturb_cameras
from linnet.sim.rig import EUROC_CAM0, EUROC_CAM1
from linnet.sim.simulator import CAMERA_EVERY, simulate
from linnet.sim.trajectory import SplineState, SplineTrajectory

RATE = 200.0


def still_then_moving(n: int, rest: int) -> SplineState:
    """A motion at rest for the first `rest` samples and moving (1 m/s along x) after, for the phase rule."""
    v = np.zeros((n, 3))
    v[rest:, 0] = 1.0
    p = np.zeros((n, 3))
    z = np.zeros((n, 3))
    return SplineState(p, np.tile([1.0, 0, 0, 0], (n, 1)), np.tile(np.eye(3), (n, 1, 1)), v, z, z, z)


def test_phase_rule_merges_short_runs():
    t = np.arange(4000, dtype=np.int64) * 5_000_000
    st = still_then_moving(4000, 1000)
    st.v[2000:2100, 0] = 0.0  # a 0.5 s pause in flight stays flight
    mask = M.flight_mask(t, st, M.PhaseRule())
    assert not mask[:1000].any() and mask[1000:].all()


def test_psd_fit_recovers_a_known_spectrum():
    """White noise of known density plus a sinusoid: the fitted flight PSD has the density's level away from the peak
    and its peak at the sinusoid's frequency; the rest phase (white only) has the white level."""
    rng = np.random.default_rng(1)
    n, rest = 200 * 120, 200 * 20
    t = np.arange(n, dtype=np.int64) * 5_000_000
    density = np.array([1e-3, 2e-3, 3e-3, 0.02, 0.03, 0.04])        # units / sqrt(Hz)
    x = rng.standard_normal((n, 6)) * density * math.sqrt(RATE / 2.0)  # one-sided PSD density^2 over 0..RATE/2
    f0, amplitude = 37.5, 0.5
    x[rest:, 3] += amplitude * np.sin(2 * math.pi * f0 * t[rest:] * 1e-9)
    model = M.fit_model(t, x, still_then_moving(n, rest), trim_s=0.0, flat_below_hz=0.0)
    f = model.freqs_hz
    away = (f > 5) & (np.abs(f - f0) > 3) & (f < 95)
    for ph in M.PHASES:
        level = np.median(model.psd[ph][:, away], axis=1)
        np.testing.assert_allclose(level, density ** 2, rtol=0.1)
    assert abs(f[np.argmax(model.psd["flight"][3])] - f0) < 0.3
    # The sinusoid's power (amplitude^2 / 2) is in the peak.
    peak = np.abs(f - f0) < 1.5
    power = (model.psd["flight"][3][peak] - density[3] ** 2).sum() * (f[1] - f[0])
    assert power == pytest.approx(amplitude ** 2 / 2, rel=0.1)
    assert model.std["rest"] == pytest.approx(density * math.sqrt(RATE / 2), rel=0.05)


def test_synthesis_reproduces_a_given_spectrum():
    """Noise synthesised from a model with a shaped spectrum (a band-pass hump on a floor) has that spectrum again
    (within 1.5 dB in each of the 9 bands of each axis: with 150 s at rest the lowest bands hold only a few
    independent estimates, about 0.4 dB 1-sigma) and the model's standard deviation."""
    freqs = np.linspace(0, 100, 513)
    shape = 1e-4 + 5e-3 * np.exp(-0.5 * ((freqs - 60.0) / 4.0) ** 2)
    psd = {ph: np.vstack([shape * (k + 1) * (2.0 if ph == "flight" else 1.0) for k in range(6)]) for ph in M.PHASES}
    std = {ph: M.band_std(freqs, psd[ph], 0, 100) for ph in M.PHASES}
    model = M.MeasuredImuModel(RATE, freqs, psd, std, {"rest": 30.0, "flight": 90.0})
    n, rest = 200 * 600, 200 * 150
    t = np.arange(n, dtype=np.int64) * 5_000_000
    st = still_then_moving(n, rest)
    noise = M.synthesize_noise(model, t, st, np.random.default_rng(5))
    refit = M.fit_model(t, noise, st, trim_s=0.0, flat_below_hz=0.0, nperseg=(1024, 1024))
    report = M.compare_models(model, refit)
    for ph in M.PHASES:
        assert report["phases"][ph]["max_abs_db"] < 1.5, (ph, report["phases"][ph]["db"])
        assert abs(np.mean(report["phases"][ph]["db"])) < 0.2
        np.testing.assert_allclose(report["phases"][ph]["std_ratio"], 1.0, atol=0.05)
    # Deterministic from the generator.
    again = M.synthesize_noise(model, t, st, np.random.default_rng(5))
    np.testing.assert_array_equal(noise, again)


def test_model_file_round_trip_and_errors(tmp_path):
    model = M.MeasuredImuModel.load(M.shipped_model_path())
    path = tmp_path / "m.yaml"
    model.save(path)
    back = M.MeasuredImuModel.load(path)
    np.testing.assert_allclose(back.psd["flight"], model.psd["flight"], rtol=1e-4)
    assert back.gyroscope_random_walk == model.gyroscope_random_walk
    noise = ImuNoise.from_spec(str(path))
    assert noise.model is not None and noise.accelerometer_random_walk == model.accelerometer_random_walk
    data = yaml.safe_load(path.read_text())
    del data["phases"]["rest"]["psd"]["acc_y"]
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(InputError, match=r"bad.yaml: missing key 'phases.rest.psd.acc_y'"):
        ImuNoise.from_spec(str(bad))


def test_shipped_model_has_the_vibration_of_the_real_flight():
    """The shipped model (fitted to V1_01_easy) is far above the datasheet's white noise in flight, and the measured
    IMU of a replay carries it."""
    noise = ImuNoise.from_spec("measured")
    model = noise.model
    assert model.seconds["flight"] > 100 and model.seconds["rest"] > 3
    # Datasheet white noise at 200 Hz: 0.0024 rad/s and 0.028 m/s^2; the flight has several times more.
    assert np.all(model.std["flight"][:3] > 5 * 0.0024) and np.all(model.std["flight"][3:] > 5 * 0.028)
    s = builtin_loop()
    spline, _ = SplineTrajectory.fit(s, int(s.t_ns[0]), int(s.t_ns[-1]))
    t = s.t_ns[0] + np.arange(4000) * 5_000_000
    imu = synthesize(spline, t, noise, np.random.default_rng(0))
    truth = spline.evaluate(t)
    err = imu.acc - truth.f_B - imu.bias_acc
    assert err.std(axis=0) == pytest.approx(model.std["flight"][3:], rel=0.2)


def test_fit_of_the_real_log_matches_the_shipped_model(shared_data):
    """`linnet sim fit-imu` on the real V1_01_easy log gives the shipped numbers."""
    mav0 = shared_data("euroc/V1_01_easy_micro/mav0")
    fitted = M.fit_files(mav0 / "imu0" / "data.csv", mav0 / "state_groundtruth_estimate0" / "data.csv")
    shipped = M.MeasuredImuModel.load(M.shipped_model_path())
    for ph in M.PHASES:
        np.testing.assert_allclose(fitted.psd[ph], shipped.psd[ph], rtol=1e-3, atol=1e-12)
        np.testing.assert_allclose(fitted.std[ph], shipped.std[ph], rtol=1e-3)


def test_fit_needs_biases_in_the_groundtruth(tmp_path):
    gt = tmp_path / "gt.tum"
    gt.write_text("".join(f"{1.0 + 0.005 * k:.3f} 0 0 0 0 0 0 1\n" for k in range(400)))
    imu = tmp_path / "imu.csv"
    imu.write_text("".join(f"{1_000_000_000 + 5_000_000 * k},0,0,0,0,0,9.81\n" for k in range(400)))
    with pytest.raises(InputError, match="no bias columns"):
        M.fit_files(imu, gt)


# ---------------------------------------------------------------------------------------------- calibration / clock


def test_calibration_error_is_written_and_read_back(tmp_path):
    """--calib-error typical: the sensor.yaml files hold the perturbed calibration (what the C++ reader loads), the
    perturbation has the documented size, and the ground truth is the same as without it."""
    args = dict(trajectory="builtin:loop", scene="room", seed=4, start=2.0, duration=1.0, imu_noise="none")
    simulate(out_dir=tmp_path / "clean", **args)
    simulate(out_dir=tmp_path / "calib", calib_error="typical", **args)
    expected, drawn = perturb_cameras([EUROC_CAM0, EUROC_CAM1], seed=4)
    core = pytest.importorskip("linnet._linnet")
    text = core.Config.for_euroc(str(tmp_path / "calib")).to_yaml()
    for cam in expected:
        assert f"{cam.intrinsics[0]:.6f}"[:8] in text, cam.intrinsics[0]
    for cam, true in zip(expected, [EUROC_CAM0, EUROC_CAM1]):
        written = (tmp_path / "calib" / "mav0" / cam.name / "sensor.yaml").read_text()
        assert f"{cam.intrinsics[0]:.12g}" in written and f"{cam.coeffs[0]:.12g}" in written
        assert f"{cam.T_B_C[0, 3]:.12g}" in written
        d = drawn[cam.name]
        assert 0.0 < d["extrinsic_rotation_error_deg"] < 1.0 and 0.0 < d["extrinsic_translation_error_m"] < 0.02
        assert max(abs(v) for v in d["intrinsics_offset_px"]) < 5 * 0.5
    for rel in ("mav0/state_groundtruth_estimate0/data.csv", "mav0/imu0/data.csv", "mav0/cam0/data.csv"):
        assert (tmp_path / "clean" / rel).read_bytes() == (tmp_path / "calib" / rel).read_bytes()
    # The stereo pair keeps its relative geometry to the documented precision: relative error << common error.
    a = CalibrationErrorAmounts()
    rel_true = np.linalg.inv(EUROC_CAM0.T_B_C) @ EUROC_CAM1.T_B_C
    rel_pert = np.linalg.inv(expected[0].T_B_C) @ expected[1].T_B_C
    assert np.linalg.norm(rel_pert[:3, 3] - rel_true[:3, 3]) < 6 * a.stereo_translation_m
    # What sets the disparity, the difference of the principal points' offsets, is the small stereo part only.
    d0, d1 = drawn["cam0"]["intrinsics_offset_px"], drawn["cam1"]["intrinsics_offset_px"]
    assert abs(d1[2] - d0[2]) < 6 * a.stereo_intrinsics_px


def test_time_offset_shifts_camera_stamps_exactly(tmp_path):
    args = dict(trajectory="builtin:loop", scene="room", seed=2, start=2.0, duration=1.0, imu_noise="none")
    simulate(out_dir=tmp_path / "a", **args)
    simulate(out_dir=tmp_path / "b", time_offset_ms=2.5, **args)

    def stamps(d):
        rows = (d / "mav0" / "cam0" / "data.csv").read_text().splitlines()[1:]
        return np.array([int(r.split(",")[0]) for r in rows], dtype=np.int64), rows

    ta, _ = stamps(tmp_path / "a")
    tb, rows = stamps(tmp_path / "b")
    imu_t = np.array([int(r.split(",")[0]) for r in
                      (tmp_path / "a" / "mav0" / "imu0" / "data.csv").read_text().splitlines()[1:]])
    np.testing.assert_array_equal(ta, imu_t[::CAMERA_EVERY][:ta.size])
    # Same frames, stamps 2.5 ms later, except a last frame pushed past the IMU's end.
    assert tb.size in (ta.size, ta.size - 1)
    np.testing.assert_array_equal(tb, ta[:tb.size] + 2_500_000)
    assert all(r.endswith(f"{t}.png") for r, t in zip(rows, tb))
    assert (tmp_path / "b" / "mav0" / "cam0" / "data" / f"{tb[0]}.png").is_file()
    # The images are the same (rendered at the true times).
    assert ((tmp_path / "a" / "mav0" / "cam0" / "data" / f"{ta[3]}.png").read_bytes() ==
            (tmp_path / "b" / "mav0" / "cam0" / "data" / f"{tb[3]}.png").read_bytes())


def test_stamp_jitter_is_bounded_and_deterministic():
    t = np.arange(1000, dtype=np.int64) * 50_000_000
    j = camera_stamps(t, 0.0, 100.0, seed=1)
    d = j - t
    assert np.abs(d).max() <= 300_000 and 80_000 < d.std() < 120_000
    np.testing.assert_array_equal(j, camera_stamps(t, 0.0, 100.0, seed=1))
    with pytest.raises(InputError, match="reorders"):
        camera_stamps(t, 0.0, 20_000.0, seed=1)
    with pytest.raises(InputError, match="finite"):
        camera_stamps(t, float("nan"), 0.0, seed=1)
