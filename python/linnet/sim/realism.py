"""What makes a replay harder than a perfect one, with its ground truth unchanged: calibration errors in the written
sensor.yaml files, a camera-to-IMU clock offset and time-stamp jitter, and the presets that combine them.

Calibration error ("typical"): the images are rendered with the true calibration, the sensor.yaml files get a
perturbed one, drawn once per replay from the seed. The 1-sigma amounts (``CalibrationErrorAmounts``) are our
assumption of what separates a careful Kalibr calibration from the truth on a VI-Sensor-like rig:
  * camera-IMU extrinsics, common to both cameras: 0.1 deg per axis of rotation and 2 mm per axis of translation
    (the camera-IMU transform is observed only through the motion, so it is the least certain part);
  * the stereo pair, cam1 relative to cam0: 0.02 deg per axis and 0.2 mm per axis (seen directly by both cameras in
    every target view, hence ten times more certain);
  * intrinsics: 0.5 px on the focal lengths and on the principal point; distortion 2e-3 on k1 and k2 and 5e-5 on p1
    and p2 (a 752x480 lens with k1 about -0.28).
Clock: ``time_offset_ms`` X makes every written camera stamp the true mid-exposure time on the IMU clock plus X ms (so
Kalibr's timeshift_cam_imu, t_imu = t_cam + shift, would be -X ms); ``stamp_jitter_us`` Y adds independent Gaussian
jitter of Y us (clipped at 3 sigma) to every camera stamp. IMU stamps and the ground truth stay on the IMU clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from linnet.sim.trajectory import InputError

CALIB_ERRORS = ("none", "typical")
REALISM_LEVELS = ("easy", "hard")

#: What each realism level sets (options given explicitly on the command line take precedence).
REALISM_PRESETS = {
    "easy": {"blur": False, "exposure_changes": False, "imu_noise": "euroc", "calib_error": "none",
             "time_offset_ms": 0.0, "stamp_jitter_us": 0.0},
    "hard": {"blur": True, "exposure_changes": True, "imu_noise": "measured", "calib_error": "typical",
             "time_offset_ms": 3.0, "stamp_jitter_us": 0.0},
}


@dataclass
class CalibrationErrorAmounts:
    """1-sigma calibration errors of ``--calib-error typical`` (see the module docstring for why)."""
    extrinsic_rotation_deg: float = 0.1       # camera-IMU rotation, per axis, degrees (common to both cameras)
    extrinsic_translation_m: float = 0.002    # camera-IMU translation, per axis, metres (common to both cameras)
    stereo_rotation_deg: float = 0.02         # cam1 relative to cam0, per axis, degrees
    stereo_translation_m: float = 0.0002      # cam1 relative to cam0, per axis, metres
    focal_px: float = 0.5                     # fx, fy, pixels
    principal_point_px: float = 0.5           # cx, cy, pixels
    radial: float = 2e-3                      # k1, k2
    tangential: float = 5e-5                  # p1, p2


def _rotation(rotvec: np.ndarray) -> np.ndarray:
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-15:
        return np.eye(3)
    k = rotvec / angle
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _transform(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T


def perturb_cameras(cameras: list, seed: int, amounts: Optional[CalibrationErrorAmounts] = None):
    """The cameras with a calibration error drawn from `seed` (deterministic). Returns (perturbed cameras, a dict of
    the errors drawn: per camera the intrinsic and distortion offsets and the extrinsic error as a rotation vector in
    degrees and a translation in metres)."""
    a = amounts or CalibrationErrorAmounts()
    rng = np.random.default_rng([int(seed), 0xCA11B])
    deg = math.pi / 180.0
    # A common error of the rig against the IMU (applied on the body side) and a relative error of cam1 (camera side).
    common = _transform(_rotation(rng.standard_normal(3) * a.extrinsic_rotation_deg * deg),
                        rng.standard_normal(3) * a.extrinsic_translation_m)
    relative = _transform(_rotation(rng.standard_normal(3) * a.stereo_rotation_deg * deg),
                          rng.standard_normal(3) * a.stereo_translation_m)
    out, drawn = [], {}
    for i, cam in enumerate(cameras):
        T = common @ cam.T_B_C @ (relative if i > 0 else np.eye(4))
        d_int = np.concatenate([rng.standard_normal(2) * a.focal_px, rng.standard_normal(2) * a.principal_point_px])
        d_dist = np.concatenate([rng.standard_normal(2) * a.radial, rng.standard_normal(2) * a.tangential])
        coeffs = list(cam.coeffs)
        coeffs[:4] = [c + d for c, d in zip(coeffs[:4], d_dist)]
        out.append(replace(cam, intrinsics=[v + d for v, d in zip(cam.intrinsics, d_int)], coeffs=coeffs, T_B_C=T))
        dT = np.linalg.inv(cam.T_B_C) @ T
        cos = np.clip((np.trace(dT[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
        drawn[cam.name] = {"intrinsics_offset_px": [float(v) for v in d_int],
                           "distortion_offset": [float(v) for v in d_dist],
                           "extrinsic_rotation_error_deg": float(math.degrees(math.acos(cos))),
                           "extrinsic_translation_error_m": float(np.linalg.norm(T[:3, 3] - cam.T_B_C[:3, 3]))}
    return out, drawn


def camera_stamps(true_t_ns: np.ndarray, time_offset_ms: float, stamp_jitter_us: float, seed: int) -> np.ndarray:
    """Written camera stamps: the true times plus the constant offset plus clipped Gaussian jitter (deterministic)."""
    if not math.isfinite(time_offset_ms) or not math.isfinite(stamp_jitter_us) or stamp_jitter_us < 0:
        raise InputError(f"--time-offset-ms must be finite and --stamp-jitter-us finite and >= 0 "
                         f"(got {time_offset_ms}, {stamp_jitter_us})")
    t = np.asarray(true_t_ns, dtype=np.int64) + int(round(time_offset_ms * 1e6))
    if stamp_jitter_us > 0:
        rng = np.random.default_rng([int(seed), 0x717E4])
        jitter = np.clip(rng.standard_normal(t.size), -3.0, 3.0) * stamp_jitter_us * 1e3
        t = t + np.round(jitter).astype(np.int64)
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise InputError(f"--stamp-jitter-us {stamp_jitter_us}: the jitter reorders camera frames; use less than a "
                         "sixth of the frame period")
    return t
