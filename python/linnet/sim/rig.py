"""The simulated sensor rig: EuRoC's VI-Sensor (two MT9M034 cameras + ADIS16448), as calibrated in the EuRoC
sensor.yaml files (cam0 / cam1 of V1_01_easy; the same calibration ships with every EuRoC Vicon-room sequence)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class CameraSpec:
    name: str
    width: int
    height: int
    intrinsics: list            # fx fy cx cy, pixels
    distortion: str             # "radtan" (k1 k2 p1 p2)
    coeffs: list
    T_B_C: np.ndarray           # 4x4, camera -> body (EuRoC's T_BS)
    rate_hz: float = 20.0
    comment: str = ""

    def renderer(self, **options):
        from linnet._linnet import sim as native
        return native.Renderer(self.width, self.height, self.intrinsics, self.distortion, self.coeffs, **options)


def _T(rows) -> np.ndarray:
    return np.array(rows, dtype=float).reshape(4, 4)


EUROC_CAM0 = CameraSpec(
    "cam0", 752, 480, [458.654, 457.296, 367.215, 248.375], "radtan",
    [-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05],
    _T([0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,
        0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,
        -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,
        0.0, 0.0, 0.0, 1.0]), comment="VI-Sensor cam0 (MT9M034), simulated")

EUROC_CAM1 = CameraSpec(
    "cam1", 752, 480, [457.587, 456.134, 379.999, 255.238], "radtan",
    [-0.28368365, 0.07451284, -0.00010473, -3.55590700e-05],
    _T([0.0125552670891, -0.999755099723, 0.0182237714554, -0.0198435579556,
        0.999598781151, 0.0130119051815, 0.0251588363115, 0.0453689425024,
        -0.0253898008918, 0.0179005838253, 0.999517347078, 0.00786212447038,
        0.0, 0.0, 0.0, 1.0]), comment="VI-Sensor cam1 (MT9M034), simulated")


@dataclass
class StereoRig:
    cameras: list = field(default_factory=lambda: [EUROC_CAM0, EUROC_CAM1])


def project(cam: CameraSpec, p_C: np.ndarray) -> np.ndarray:
    """Pinhole + radtan projection of (N, 3) camera-frame points to distorted pixels (N, 2) (NaN behind)."""
    z = p_C[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        x, y = p_C[:, 0] / z, p_C[:, 1] / z
    k1, k2, p1, p2 = cam.coeffs[:4]
    r2 = x * x + y * y
    radial = 1 + k1 * r2 + k2 * r2 * r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    fx, fy, cx, cy = cam.intrinsics
    px = np.stack([fx * xd + cx, fy * yd + cy], axis=1)
    px[z <= 1e-6] = np.nan
    return px
