"""Synthetic IMU from the continuous-time trajectory, or a real IMU log, plus the noise model.

Noise model (Kalibr / EuRoC imu0 sensor.yaml convention, continuous-time densities), sampled at period dt:
    measurement = truth + bias_k + n_k,  n_k ~ N(0, density^2 / dt)
    bias_{k+1}  = bias_k + w_k,          w_k ~ N(0, random_walk^2 * dt)
The true biases are written to the ground truth (b_w, b_a columns of state_groundtruth_estimate0).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from linnet.sim.trajectory import InputError, SplineTrajectory

IMU_RATE_HZ = 200.0
IMU_PERIOD_NS = 5_000_000


@dataclass
class ImuNoise:
    """Defaults: the ADIS16448 of EuRoC (mav0/imu0/sensor.yaml of the V1_01 micro set)."""
    gyroscope_noise_density: float = 1.6968e-04      # rad/s/sqrt(Hz)
    gyroscope_random_walk: float = 1.9393e-05        # rad/s^2/sqrt(Hz)
    accelerometer_noise_density: float = 2.0000e-3   # m/s^2/sqrt(Hz)
    accelerometer_random_walk: float = 3.0000e-3     # m/s^3/sqrt(Hz)
    initial_gyro_bias_sigma: float = 0.01            # rad/s, std of the random initial gyroscope bias
    initial_accel_bias_sigma: float = 0.05           # m/s^2, std of the random initial accelerometer bias

    @classmethod
    def none(cls) -> "ImuNoise":
        return cls(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)

    @classmethod
    def from_spec(cls, spec: str) -> "ImuNoise":
        """"euroc", "none", or a YAML file with any of the field names (a Kalibr imu sensor.yaml works)."""
        if spec == "euroc":
            return cls()
        if spec == "none":
            return cls.none()
        path = Path(spec)
        if not path.is_file():
            raise InputError(f"--imu-noise: '{spec}' is neither 'euroc', 'none' nor an existing YAML file")
        text = path.read_text(encoding="utf-8")
        if text.startswith("%YAML"):  # OpenCV-style header that PyYAML rejects
            text = text.split("\n", 1)[1]
        try:
            data = yaml.safe_load(text) or {}
        except yaml.YAMLError as e:
            raise InputError(f"{path}: not valid YAML: {e}") from None
        noise = cls()
        for key, value in data.items():
            if key in asdict(noise):
                if not isinstance(value, (int, float)) or value < 0:
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
    ng = rng.standard_normal((n, 3)) * noise.gyroscope_noise_density / np.sqrt(dt)
    na = rng.standard_normal((n, 3)) * noise.accelerometer_noise_density / np.sqrt(dt)
    return ImuData(t_ns, st.omega_B + bg + ng, st.f_B + ba + na, bg, ba)


def load_real_imu(path: str) -> ImuData:
    """A EuRoC imu0/data.csv (t_ns, w_xyz, a_xyz). Biases unknown: zeros (filled from the trajectory when known)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"--real-imu: {p}: file not found")
    t, vals = [], []
    with open(p, "r", encoding="utf-8") as f:
        for lineno, raw in enumerate(f, 1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            fields = line.split(",")
            if len(fields) != 7:
                raise InputError(f"{p}:{lineno}: expected 7 columns (t_ns, w_xyz, a_xyz), found {len(fields)}")
            try:
                t.append(int(fields[0]))
                vals.append([float(x) for x in fields[1:]])
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
