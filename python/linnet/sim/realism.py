"""What makes a replay harder than a perfect one, with its ground truth unchanged: calibration errors in the written
sensor.yaml files, a camera-to-IMU clock offset and time-stamp jitter, and the presets that combine them.

Calibration error ("typical"): the images are rendered with the true calibration, the sensor.yaml files get a
perturbed one, drawn once per replay from the seed. The 1-sigma amounts (``CalibrationErrorAmounts``) are our
assumption of what separates a careful Kalibr calibration from the truth on a VI-Sensor-like rig. Errors are drawn as
a calibration makes them: what the target constrains jointly is perturbed jointly.
  * camera-IMU extrinsics, common to both cameras: 0.1 deg per axis of rotation and 2 mm per axis of translation
    (the camera-IMU transform is observed only through the motion, so it is the least certain part);
  * intrinsics common to both cameras: 0.5 px on the focal lengths and on the principal point (each camera alone is
    known to about that); radial distortion drawn by its effect in the image, 0.3 px at the image corners and 0.1 px
    half-way out (k1 and k2 are drawn together: their errors compensate over the target's views, so independent
    draws of 2e-3 each would move the corners by up to 2 px); 5e-5 on p1 and p2;
  * the stereo pair: cam1 relative to cam0 0.01 deg per axis and 0.1 mm per axis, and 0.1 px between the two cameras'
    focal lengths and principal points. Kalibr fits the pair to target corners seen by both cameras at once, which
    pins what sets the disparity (the principal points' difference and the relative yaw) to about the corners'
    reprojection error. Independent 0.5 px errors per camera would instead bias every disparity by about 0.7 px, a 4 %
    depth error at 3 m: a replay with that is much harder than a calibrated rig (V1_01_easy hard: APE 0.136 m and a
    path 4.4 % short, against 0.024 m with the true calibration).
Clock: ``time_offset_ms`` X makes every written camera stamp the true mid-exposure time on the IMU clock plus X ms (so
Kalibr's timeshift_cam_imu, t_imu = t_cam + shift, would be -X ms); ``stamp_jitter_us`` Y adds independent Gaussian
jitter of Y us (clipped at 3 sigma) to every camera stamp. IMU stamps and the ground truth stay on the IMU clock.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np

from linnet.sim.rotations import exp_so3, pose_matrix
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
    stereo_rotation_deg: float = 0.01         # cam1 relative to cam0, per axis, degrees
    stereo_translation_m: float = 0.0001      # cam1 relative to cam0, per axis, metres
    focal_px: float = 0.5                     # fx, fy, pixels, common to both cameras
    principal_point_px: float = 0.5           # cx, cy, pixels, common to both cameras
    stereo_intrinsics_px: float = 0.1         # fx, fy, cx, cy, pixels, per camera on top of the common error
    radial_corner_px: float = 0.3             # radial distortion error at the image corners, pixels
    radial_half_px: float = 0.1               # radial distortion error half-way to the corners, pixels
    tangential: float = 5e-5                  # p1, p2


def _corner_radius(cam) -> float:
    """Undistorted normalised radius of the image corner farthest from the principal point (radtan k1, k2)."""
    fx, fy, cx, cy = cam.intrinsics
    rd = max(math.hypot((u - cx) / fx, (v - cy) / fy) for u in (0, cam.width) for v in (0, cam.height))
    k1, k2 = cam.coeffs[0], cam.coeffs[1]
    r = rd
    for _ in range(50):  # fixed point of r (1 + k1 r^2 + k2 r^4) = rd
        r = rd / (1.0 + k1 * r * r + k2 * r ** 4)
    return r


def _radial_error(cam, corner_px: float, half_px: float):
    """(dk1, dk2) moving image points radially by corner_px at the corner radius and half_px at half of it."""
    r2 = _corner_radius(cam)
    r1 = 0.5 * r2
    f = 0.5 * (cam.intrinsics[0] + cam.intrinsics[1])
    A = np.array([[r1 ** 3, r1 ** 5], [r2 ** 3, r2 ** 5]])
    return np.linalg.solve(A, np.array([half_px, corner_px]) / f)


def perturb_cameras(cameras: list, seed: int, amounts: Optional[CalibrationErrorAmounts] = None):
    """The cameras with a calibration error drawn from `seed` (deterministic). Returns (perturbed cameras, a dict of
    the errors drawn: per camera the intrinsic and distortion offsets and the extrinsic error as a rotation vector in
    degrees and a translation in metres)."""
    a = amounts or CalibrationErrorAmounts()
    rng = np.random.default_rng([int(seed), 0xCA11B])
    deg = math.pi / 180.0
    # A common error of the rig against the IMU (applied on the body side) and a relative error of cam1 (camera side).
    common = pose_matrix(exp_so3(rng.standard_normal(3) * a.extrinsic_rotation_deg * deg),
                        rng.standard_normal(3) * a.extrinsic_translation_m)
    relative = pose_matrix(exp_so3(rng.standard_normal(3) * a.stereo_rotation_deg * deg),
                          rng.standard_normal(3) * a.stereo_translation_m)
    common_int = np.concatenate([rng.standard_normal(2) * a.focal_px, rng.standard_normal(2) * a.principal_point_px])
    radial_px = rng.standard_normal(2) * [a.radial_corner_px, a.radial_half_px]
    common_dist = np.concatenate([_radial_error(cameras[0], radial_px[0], radial_px[1]),
                                  rng.standard_normal(2) * a.tangential])
    out, drawn = [], {}
    for i, cam in enumerate(cameras):
        T = common @ cam.T_B_C @ (relative if i > 0 else np.eye(4))
        d_int = common_int + rng.standard_normal(4) * a.stereo_intrinsics_px
        d_dist = common_dist
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
