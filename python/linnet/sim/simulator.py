"""The trajectory-replay simulator: a trajectory (file or built-in) + a procedural scene -> a EuRoC ASL dataset with
rendered stereo images, IMU, ground truth and the scene's 3D lines and corners. See `simulate`."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import cv2
import numpy as np

from linnet.sim import writer
from linnet.sim.imu import IMU_PERIOD_NS, ImuData, ImuNoise, interpolate_biases, load_real_imu, synthesize
from linnet.sim.realism import CALIB_ERRORS, camera_stamps, perturb_cameras
from linnet.sim.rig import EUROC_CAM0, EUROC_CAM1
from linnet.sim.rotations import pose_matrix
from linnet.sim.scene import SCENES, SceneSpec, build_scene
from linnet.sim.trajectory import (InputError, SplineState, SplineTrajectory, TrajectorySamples,
                                   load_trajectory)

CAMERA_EVERY = 10            # one stereo frame every 10 IMU samples: 20 Hz on the IMU clock, as in EuRoC
EXPOSURE_S = 0.010           # exposure time for motion blur, s
BLUR_SUBFRAMES = 5           # sub-frames averaged for motion blur
PNG_COMPRESSION = 0          # zlib level of the PNGs: 0 stores them uncompressed, as EuRoC's own PNGs are (sensor noise
                             # defeats compression anyway: level 1 with Huffman coding only saves 40%)
# Row filter "none": with stored data this makes decoding nearly a copy. One 752x480 image on one core with the system
# libpng: 0.25 ms, against 1.8 ms for stored Paeth-filtered rows (EuRoC's own files) and 4.0 ms for level 1 Huffman.
# Older OpenCV builds without the flag fall back to libpng's adaptive filters.
PNG_PARAMS = [cv2.IMWRITE_PNG_COMPRESSION, PNG_COMPRESSION]
if hasattr(cv2, "IMWRITE_PNG_FILTER") and hasattr(cv2, "IMWRITE_PNG_FILTER_NONE"):
    PNG_PARAMS += [cv2.IMWRITE_PNG_FILTER, cv2.IMWRITE_PNG_FILTER_NONE]
MIN_DURATION_S = 1.0


def _exposure_gains(t_s: np.ndarray, rng: np.random.Generator, enabled: bool) -> np.ndarray:
    """Per-frame gains of cam0 and cam1, (N, 2). Auto-exposure-like: slow drift plus occasional smooth jumps of
    +-30 %, the two cameras adjusting slightly differently."""
    if not enabled:
        return np.ones((t_s.size, 2))
    dur = float(t_s[-1] - t_s[0]) + 1.0
    n_jumps = rng.poisson(0.25 * dur)
    jump_t = np.sort(rng.uniform(0, dur, n_jumps))
    jump_a = rng.normal(0.0, 0.3, n_jumps)
    tt = t_s - t_s[0]
    log_g = np.zeros((t_s.size, 2))
    for c in range(2):
        phase = rng.uniform(0, 2 * math.pi, 2)
        log_g[:, c] = 0.15 * np.sin(2 * math.pi * tt / 7.0 + phase[0]) + 0.05 * np.sin(2 * math.pi * tt / 2.3 +
                                                                                      phase[1])
        for tj, aj in zip(jump_t, jump_a):
            x = np.clip((tt - tj - 0.03 * c) / 0.25, 0, 1)
            log_g[:, c] += aj * x * x * (3 - 2 * x)
    return np.clip(np.exp(log_g), 0.4, 2.0)


@dataclass
class Replay:
    """Everything a simulated sequence is made of, before any file is written."""
    samples: TrajectorySamples
    spline: SplineTrajectory
    fit: dict
    imu_t: np.ndarray            # (N,) int64 IMU time stamps, ns
    state: SplineState           # ground truth at imu_t
    imu: ImuData                 # measurements and true biases at imu_t
    noise: Optional[ImuNoise]    # None with a real IMU
    cam_t: np.ndarray            # (M,) int64 camera time stamps (every CAMERA_EVERY-th IMU stamp), ns
    cameras: list                # [CameraSpec cam0, cam1]
    scene: SceneSpec


def prepare(trajectory: str, scene: str, seed: int = 0, start: float = 0.0, duration: Optional[float] = None,
            imu_noise: str = "euroc", real_imu: Optional[str] = None, knot_dt: float = 0.1) -> Replay:
    """Loads and fits the trajectory, makes the IMU and builds the scene (deterministic from the arguments)."""
    if scene not in SCENES:
        raise InputError(f"unknown scene '{scene}' (known: {', '.join(SCENES)})")
    if not (math.isfinite(start) and start >= 0):
        raise InputError(f"--start must be a finite number of seconds >= 0, got {start}")
    if duration is not None and not (math.isfinite(duration) and duration >= MIN_DURATION_S):
        raise InputError(f"--duration must be >= {MIN_DURATION_S} s, got {duration}")
    noise = ImuNoise.from_spec(imu_noise) if real_imu is None else None
    samples = load_trajectory(trajectory)
    t_first = int(samples.t_ns[0]) + int(round(start * 1e9))
    t_last = int(samples.t_ns[-1])
    if duration is not None:
        t_last = min(t_last, t_first + int(round(duration * 1e9)))

    # IMU time stamps: the real log's within the range, or a regular 200 Hz grid from the start.
    if real_imu is not None:
        real = load_real_imu(real_imu)
        keep = (real.t_ns >= t_first) & (real.t_ns <= t_last)
        if keep.sum() < 2:
            raise InputError(f"--real-imu: {real_imu}: no IMU samples inside the trajectory's time range")
        imu_t = real.t_ns[keep]
    else:
        n = max(0, (t_last - t_first) // IMU_PERIOD_NS + 1)
        imu_t = t_first + np.arange(n, dtype=np.int64) * IMU_PERIOD_NS
    if imu_t.size < 2 or (imu_t[-1] - imu_t[0]) * 1e-9 < MIN_DURATION_S:
        raise InputError(f"{samples.source}: less than {MIN_DURATION_S} s of trajectory after --start {start}")

    spline, fit = SplineTrajectory.fit(samples, int(imu_t[0]), int(imu_t[-1]), dt=knot_dt)
    state = spline.evaluate(imu_t)
    if real_imu is not None:
        imu = ImuData(imu_t, real.gyr[keep], real.acc[keep],
                      interpolate_biases(imu_t, samples.t_ns, samples.bias_gyr),
                      interpolate_biases(imu_t, samples.t_ns, samples.bias_acc))
    else:
        imu = synthesize(spline, imu_t, noise, np.random.default_rng(seed))
    cams = [EUROC_CAM0, EUROC_CAM1]
    # Path points the scene must keep clear of: body and camera centres along the whole path, every 5 ms.
    centres = [state.p] + [state.p + state.R @ cam.T_B_C[:3, 3] for cam in cams]
    scene_spec = build_scene(scene, np.vstack(centres), seed)
    return Replay(samples, spline, fit, imu_t, state, imu, noise, imu_t[::CAMERA_EVERY], cams, scene_spec)


def simulate(trajectory: str, scene: str, out_dir, seed: int = 0, start: float = 0.0,
             duration: Optional[float] = None, imu_noise: str = "euroc", real_imu: Optional[str] = None,
             blur: bool = False, exposure_changes: bool = False,
             progress: Optional[Callable[[int, int], None]] = None, render_options: Optional[dict] = None,
             knot_dt: float = 0.1, calib_error: str = "none", time_offset_ms: float = 0.0,
             stamp_jitter_us: float = 0.0) -> dict:
    """Simulates a EuRoC-like stereo + IMU sequence and writes it to `out_dir` (the folder that will hold mav0/).

    trajectory: TUM / EuRoC csv path, or "builtin:loop". scene: one of SCENES. start / duration: seconds into the
    trajectory. imu_noise: "euroc" | "none" | "measured" | YAML file (ignored with real_imu). real_imu: a EuRoC
    imu0/data.csv whose samples replace the synthetic IMU (images are still rendered from the trajectory).
    calib_error ("none" | "typical"), time_offset_ms and stamp_jitter_us: see linnet.sim.realism (the ground truth is
    unchanged). Returns a summary dict:
    frames, duration_s, render_s (wall), render_cpu_s, stereo_fps, fit (residual), scene stats, out_dir.
    Same arguments -> byte-identical files.
    """
    if calib_error not in CALIB_ERRORS:
        raise InputError(f"unknown --calib-error '{calib_error}' (known: {', '.join(CALIB_ERRORS)})")
    rp = prepare(trajectory, scene, seed, start, duration, imu_noise, real_imu, knot_dt)
    stamps = camera_stamps(rp.cam_t, time_offset_ms, stamp_jitter_us, seed)
    spline, imu_t, state, imu, noise, cam_t, cams, scene_spec = (rp.spline, rp.imu_t, rp.state, rp.imu, rp.noise,
                                                                 rp.cam_t, rp.cameras, rp.scene)
    # Frames whose written stamp would fall outside the IMU's time range (a clock offset at either end) are left out.
    inside = (stamps >= imu_t[0]) & (stamps <= imu_t[-1])
    cam_t, stamps = cam_t[inside], stamps[inside]
    fit = rp.fit
    cam_state = spline.evaluate(cam_t)
    native_scene = scene_spec.to_native()
    opts = dict(render_options or {})
    if blur:
        opts.setdefault("supersample", 1)
    renderers = [cam.renderer(**opts) for cam in cams]
    gains = _exposure_gains((cam_t - cam_t[0]) * 1e-9, np.random.default_rng([seed, 7]), exposure_changes)

    out = Path(out_dir)
    mav0 = out / "mav0"
    writer.write_body(mav0)
    written, calib_drawn = (perturb_cameras(cams, seed) if calib_error == "typical" else (cams, None))
    img_dirs = [writer.write_camera(mav0, cam, stamps) for cam in written]
    t0_wall, t0_cpu = time.perf_counter(), time.process_time()
    for k, t in enumerate(cam_t):
        T_W_B = pose_matrix(cam_state.R[k], cam_state.p[k])
        if blur:
            sub_t = t + np.round((np.arange(BLUR_SUBFRAMES) / (BLUR_SUBFRAMES - 1) - 0.5) * EXPOSURE_S * 1e9
                                 ).astype(np.int64)
            sub = spline.evaluate(sub_t)
        for c, (cam, r) in enumerate(zip(cams, renderers)):
            noise_seed = (int(seed) * 1_000_003 + k) * 2 + c
            if blur:
                poses = [pose_matrix(sub.R[j], sub.p[j]) @ cam.T_B_C for j in range(BLUR_SUBFRAMES)]
                img = r.expose(r.render_radiance_blurred(native_scene, poses), float(gains[k, c]), noise_seed)
            else:
                img = r.render(native_scene, T_W_B @ cam.T_B_C, float(gains[k, c]), noise_seed)
            cv2.imwrite(str(img_dirs[c] / f"{int(stamps[k])}.png"), img, PNG_PARAMS)
        if progress is not None:
            progress(k + 1, cam_t.size)
    render_s, render_cpu = time.perf_counter() - t0_wall, time.process_time() - t0_cpu

    writer.write_imu(mav0, imu, noise if noise is not None else ImuNoise())
    writer.write_groundtruth(mav0, imu_t, state, imu.bias_gyr, imu.bias_acc)
    duration_s = float(imu_t[-1] - imu_t[0]) * 1e-9
    info = {
        "arguments": {"trajectory": str(trajectory), "scene": scene, "seed": int(seed), "start": float(start),
                      "duration": None if duration is None else float(duration), "imu_noise": imu_noise,
                      "real_imu": None if real_imu is None else str(real_imu), "blur": bool(blur),
                      "exposure_changes": bool(exposure_changes), "knot_dt": float(knot_dt),
                      "calib_error": calib_error, "time_offset_ms": float(time_offset_ms),
                      "stamp_jitter_us": float(stamp_jitter_us)},
        "calibration_error_drawn": calib_drawn,
        "fit": fit,
        "imu_noise_used": None if noise is None else noise.numbers(),
        "imu_noise_model": None if noise is None or noise.model is None else noise.model.source,
        "frames": int(cam_t.size), "imu_samples": int(imu_t.size), "duration_s": duration_s,
        "t_first_ns": int(imu_t[0]), "t_last_ns": int(imu_t[-1]),
        "scene": {"name": scene, "quads": len(scene_spec.quads), "lines": len(scene_spec.lines),
                  "points": len(scene_spec.points), "dropped_objects": int(scene_spec.dropped_objects),
                  "bounds_min": [float(v) for v in scene_spec.bounds[0]],
                  "bounds_max": [float(v) for v in scene_spec.bounds[1]]},
    }
    writer.write_scene_truth(out / "sim", scene_spec, info)
    return {
        "out_dir": str(out), "frames": int(cam_t.size), "duration_s": duration_s, "render_s": render_s,
        "render_cpu_s": render_cpu, "stereo_fps": cam_t.size / max(render_s, 1e-9),
        "stereo_fps_cpu": cam_t.size / max(render_cpu, 1e-9), "fit": fit, "scene": info["scene"],
    }
