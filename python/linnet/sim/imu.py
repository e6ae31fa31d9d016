"""Synthetic IMU from the continuous-time trajectory, or a real IMU log, plus the noise model.

Noise model (Kalibr / EuRoC imu0 sensor.yaml convention, continuous-time densities), sampled at period dt:
    measurement = truth + bias_k + n_k,  n_k ~ N(0, density^2 / dt)
    bias_{k+1}  = bias_k + w_k,          w_k ~ N(0, random_walk^2 * dt)
With a measured model (``--imu-noise measured``, see linnet.sim.imu_model) n_k is coloured noise with the spectra of a
real flight's IMU error instead (vibration included), the bias walks as above with the model's densities.
The true biases are written to the ground truth (b_w, b_a columns of state_groundtruth_estimate0).
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from linnet.fileio import read_text_file
from linnet.sim.imu_model import MODEL_KIND, MeasuredImuModel, shipped_model_path, synthesize_noise
from linnet.sim.trajectory import InputError, SplineTrajectory

IMU_RATE_HZ = 200.0
IMU_PERIOD_NS = 5_000_000


#: The --imu-noise values that are not files.
IMU_NOISE_KEYWORDS = ("euroc", "none", "measured")

@dataclass
class ImuNoise:
    """Defaults: the ADIS16448 of EuRoC (mav0/imu0/sensor.yaml of the V1_01 micro set)."""
    gyroscope_noise_density: float = 1.6968e-04      # rad/s/sqrt(Hz)
    gyroscope_random_walk: float = 1.9393e-05        # rad/s^2/sqrt(Hz)
    accelerometer_noise_density: float = 2.0000e-3   # m/s^2/sqrt(Hz)
    accelerometer_random_walk: float = 3.0000e-3     # m/s^3/sqrt(Hz)
    initial_gyro_bias_sigma: float = 0.01            # rad/s, std of the random initial gyroscope bias
    initial_accel_bias_sigma: float = 0.05           # m/s^2, std of the random initial accelerometer bias
    # A measured noise model: replaces the white noise (the two densities above stay the datasheet's, written to the
    # replay's imu0/sensor.yaml as a real EuRoC folder has them).
    model: Optional[MeasuredImuModel] = None

    def numbers(self) -> dict:
        """The scalar fields (densities, random walks, initial bias spreads)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self) if f.name != "model"}

    @classmethod
    def none(cls) -> "ImuNoise":
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def measured(cls, model: MeasuredImuModel) -> "ImuNoise":
        return cls(gyroscope_random_walk=model.gyroscope_random_walk,
                   accelerometer_random_walk=model.accelerometer_random_walk,
                   initial_gyro_bias_sigma=model.initial_gyro_bias_sigma,
                   initial_accel_bias_sigma=model.initial_accel_bias_sigma, model=model)

    @classmethod
    def from_spec(cls, spec: str) -> "ImuNoise":
        """"euroc", "none", "measured" (the shipped model fitted to EuRoC V1_01_easy), a measured model file (``linnet
        sim fit-imu``), or a YAML file with any of the field names (a Kalibr imu sensor.yaml works)."""
        if spec == "euroc":
            return cls()
        if spec == "none":
            return cls.none()
        if spec == "measured":
            return cls.measured(MeasuredImuModel.load(shipped_model_path()))
        path = Path(spec)
        if not path.is_file():
            raise InputError(f"--imu-noise: '{spec}' is neither {', '.join(IMU_NOISE_KEYWORDS)} nor an existing "
                             "YAML file")
        text = read_text_file(path, "an IMU noise YAML file")
        if text.startswith("%YAML"):  # OpenCV-style header that PyYAML rejects
            text = text.split("\n", 1)[1]
        try:
            data = yaml.safe_load(text) or {}
        except yaml.YAMLError as e:
            raise InputError(f"{path}: not valid YAML: {e}") from None
        if isinstance(data, dict) and isinstance(data.get("imu0"), dict):  # Kalibr imu.yaml: keys under imu0
            data = data["imu0"]
        if isinstance(data, dict) and data.get("kind") == MODEL_KIND:
            return cls.measured(MeasuredImuModel.from_dict(data, str(path)))
        noise = cls()
        known = noise.numbers()
        found = [key for key in (data if isinstance(data, dict) else {}) if key in known]
        if not found:
            raise InputError(f"{path}: no IMU noise key (expected some of: {', '.join(sorted(known))}; or a model "
                             "from linnet sim fit-imu)")
        for key in found:
            value = data[key]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0 or value == float("inf"):
                raise InputError(f"{path}: key '{key}' must be a non-negative number, got {value!r}")
            setattr(noise, key, float(value))
        return noise


@dataclass
class ImuData:
    t_ns: np.ndarray       # (N,) int64
    gyr: np.ndarray        # (N, 3) rad/s, measured
    acc: np.ndarray        # (N, 3) m/s^2, measured
    bias_gyr: np.ndarray   # (N, 3) true gyroscope bias
    bias_acc: np.ndarray   # (N, 3) true accelerometer bias


def synthesize(spline: SplineTrajectory, t_ns: np.ndarray, noise: ImuNoise,
               rng: np.random.Generator) -> ImuData:
    """IMU samples at t_ns (a regular 200 Hz grid) from the spline's exact angular rate and specific force."""
    st = spline.evaluate(t_ns)
    n = t_ns.size
    dt = IMU_PERIOD_NS * 1e-9
    # Draw every random number in one fixed order: initial biases, bias walks, white noise (determinism).
    bg0 = rng.standard_normal(3) * noise.initial_gyro_bias_sigma
    ba0 = rng.standard_normal(3) * noise.initial_accel_bias_sigma
    walk_g = rng.standard_normal((n, 3)) * noise.gyroscope_random_walk * np.sqrt(dt)
    walk_a = rng.standard_normal((n, 3)) * noise.accelerometer_random_walk * np.sqrt(dt)
    walk_g[0] = walk_a[0] = 0.0
    bg = bg0 + np.cumsum(walk_g, axis=0)
    ba = ba0 + np.cumsum(walk_a, axis=0)
    if noise.model is not None:
        coloured = synthesize_noise(noise.model, t_ns, st, rng)
        ng, na = coloured[:, :3], coloured[:, 3:]
    else:
        ng = rng.standard_normal((n, 3)) * noise.gyroscope_noise_density / np.sqrt(dt)
        na = rng.standard_normal((n, 3)) * noise.accelerometer_noise_density / np.sqrt(dt)
    return ImuData(t_ns, st.omega_B + bg + ng, st.f_B + ba + na, bg, ba)


def load_real_imu(path: str, what: str = "--real-imu") -> ImuData:
    """A EuRoC imu0/data.csv (t_ns, w_xyz, a_xyz). Biases unknown: zeros (filled from the trajectory when known)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{what}: {p}: file not found")
    t, vals = [], []
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(f"{what}: {p}: not a text file (expected a EuRoC imu0/data.csv)") from None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        cols = line.split(",")
        if len(cols) != 7:
            raise InputError(f"{p}:{lineno}: expected 7 columns (t_ns, w_xyz, a_xyz), found {len(cols)}")
        try:
            t.append(int(cols[0]))
            vals.append([float(x) for x in cols[1:]])
        except ValueError:
            raise InputError(f"{p}:{lineno}: cannot parse '{line[:60]}'") from None
        if len(t) > 1 and t[-1] <= t[-2]:
            raise InputError(f"{p}:{lineno}: time stamps not strictly increasing")
    if len(t) < 2:
        raise InputError(f"{p}: no IMU samples")
    v = np.array(vals)
    z = np.zeros((len(t), 3))
    return ImuData(np.array(t, dtype=np.int64), v[:, :3], v[:, 3:], z, z.copy())


def interpolate_biases(t_ns: np.ndarray, src_t: np.ndarray, src_b: Optional[np.ndarray]) -> np.ndarray:
    if src_b is None:
        return np.zeros((t_ns.size, 3))
    x = (src_t - src_t[0]).astype(float)
    xi = (t_ns - src_t[0]).astype(float)
    return np.stack([np.interp(xi, x, src_b[:, k]) for k in range(3)], axis=1)
