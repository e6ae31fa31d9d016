"""High-level Python API: run a dataset, collect the outputs a user wants (files, summary, error)."""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, List, Optional, Sequence, Union

from linnet import _linnet

PathLike = Union[str, Path]


#: Ground-truth files of a mav0 folder, first found wins: EuRoC's estimate, then TUM-VI's motion capture (8 columns:
#: t, p, q wxyz; it covers the start and the end of a TUM-VI sequence only).
GROUND_TRUTH_FILES = ("state_groundtruth_estimate0/data.csv", "mocap0/data.csv")


def find_ground_truth(dataset: PathLike) -> Optional[Path]:
    """The ground-truth csv of a EuRoC-format folder (holding mav0/ or mav0 itself; GROUND_TRUTH_FILES), or None."""
    root = Path(dataset)
    for mav0 in (root / "mav0", root):
        for name in GROUND_TRUTH_FILES:
            gt = mav0 / name
            if gt.is_file():
                return gt
    return None


@dataclass
class Calibration:
    """Calibration files to use instead of a dataset's sensor.yaml files: a Kalibr camchain (camchain-imucam.yaml;
    one camera: monocular) and a Kalibr imu.yaml (noise densities and random walks). rate_hz: camera frame rate, Hz,
    for sources that do not give it (camchains do not hold it)."""

    camchain: str = ""
    imu_yaml: str = ""
    rate_hz: float = 20.0


def load_config(dataset: Optional[PathLike], config_file: Optional[PathLike] = None,
                overrides: Union[str, Sequence[str], None] = None, calib: Optional[Calibration] = None,
                base: Optional[_linnet.Config] = None) -> _linnet.Config:
    """Defaults (or `base`) + the calibration + the keys of `config_file` + `overrides`.

    The calibration is the dataset's sensor.yaml files, or the Kalibr files of `calib` (then `dataset` may be None,
    for a source without calibration files such as a ROS bag), or the cam0 / imu sections of `config_file` when it
    has them (config/tumvi_stereo_imu.yaml: then the dataset's sensor.yaml files are not read). `overrides` is YAML text, or "KEY=VALUE" strings
    (dotted keys, YAML values) applied in order; errors name the offending "--set KEY=VALUE".
    """
    calib = calib or Calibration()
    if config_file is not None and not calib.camchain and holds_calibration(config_file):
        cfg = base or _linnet.Config()  # the file's cam0 / cam1 / imu sections are the calibration (merged below)
    elif dataset is not None:
        cfg = _linnet.Config.for_euroc(str(dataset), base, camchain=calib.camchain, imu_yaml=calib.imu_yaml)
    elif calib.camchain:
        cfg = _linnet.Config.for_kalibr(calib.camchain, calib.imu_yaml, calib.rate_hz, base)
    else:
        raise _linnet.UsageError("no calibration: give a EuRoC folder or a Kalibr camchain (--calib)")
    return apply_settings(cfg, config_file, overrides)


def apply_settings(cfg: _linnet.Config, config_file: Optional[PathLike] = None,
                   overrides: Union[str, Sequence[str], None] = None) -> _linnet.Config:
    """`cfg` with the keys of `config_file` and then `overrides` (YAML text, or "KEY=VALUE" strings applied in order;
    errors name the offending "--set KEY=VALUE"). Returns `cfg`."""
    if config_file is not None:
        cfg.merge(str(config_file))
    if isinstance(overrides, str):
        if overrides:
            cfg.merge_yaml(overrides, "<overrides>")
    else:
        for item in overrides or ():
            key, sep, value = item.partition("=")
            if not sep or not key.strip():
                raise _linnet.UsageError(f"--set {item}: expected KEY=VALUE, e.g. pipeline.use_lines=false")
            cfg.set(key.strip(), value, source=f"--set {item}")
    return cfg


def config_value(config: _linnet.Config, dotted_key: str):
    """The value of one config key, e.g. config_value(cfg, "estimator.init.gravity_window_s")."""
    import yaml

    node = yaml.safe_load(config.to_yaml())
    for part in dotted_key.split("."):
        node = node[part]
    return node


def holds_calibration(config_file: PathLike) -> bool:
    """True when a config file has its own cam0 and imu sections."""
    import yaml

    from linnet.fileio import InputError, read_text_file

    try:
        doc = yaml.safe_load(read_text_file(Path(config_file), "a config file"))
    except yaml.YAMLError as e:
        raise InputError(f"{config_file}: invalid YAML ({e})") from None
    return isinstance(doc, dict) and isinstance(doc.get("cam0"), dict) and isinstance(doc.get("imu"), dict)


def run_dataset(dataset: PathLike, config: Optional[_linnet.Config] = None, *, max_frames: int = -1,
                start: float = 0.0, out: Optional[PathLike] = None,
                progress: Optional[Callable[[int, int], None]] = None) -> dict:
    """Runs a EuRoC folder (blocking, deterministic) and returns the trajectory as numpy arrays.

    The returned dict holds t_ns, position, quaternion_xyzw, velocity, bias_acc, bias_gyr (frames with a pose), and
    "summary" (frames, init time, real-time factor, APE if the dataset has ground truth). With `out`, the run's
    files (trajectory.tum/.csv, timing.csv, map.ply, summary.json) are written there.
    """
    if config is None:
        config = load_config(dataset)
    run = _linnet.run_euroc(str(dataset), config, max_frames, start, progress)
    summary = summarize(run, dataset)
    if out is not None:
        write_outputs(run, summary, out)
    result = run.trajectory(True)
    result["summary"] = summary
    result["map"] = run.map()
    return result


def extrinsics_correction(T, key: str = "T_B_R") -> dict:
    """An online extrinsics correction as summary.json gives it: the 4x4 matrix under `key` (the rig's T_B_R: the
    cameras are at T_B_R @ T_B_Ci, with T_B_Ci the calibration's; cam1's S: cam1 is at T_B_R @ T_B_C1 @ S) and its
    rotation angle and translation length."""
    import numpy as np

    from linnet.sim.rotations import log_so3

    T = np.asarray(T, dtype=float)
    return {key: T.tolist(), "rotation_deg": float(np.degrees(np.linalg.norm(log_so3(T[:3, :3])))),
            "translation_m": float(np.linalg.norm(T[:3, 3]))}


def summarize(run: "_linnet.RunSummary", dataset: Optional[PathLike]) -> dict:
    """summary.json contents: counts, timings, the run's warnings, its status ("ok" or "failed", with the reasons in
    "problems", see diagnose), and the APE (SE3 alignment, position) when the dataset has ground truth."""
    status, problems = diagnose(run)
    summary = {
        "dataset": str(dataset) if dataset is not None else None,
        "status": status,
        "problems": problems,
        "warnings": list(run.warnings),
        "stereo": run.stereo,
        "frames": run.frames,
        "processed_frames": run.processed_frames,
        "frames_with_pose": run.frames_with_pose,
        "dropped_frames": run.dropped_frames,
        "initialisation_time_s": run.init_time_s,
        "reinitialisations": run.reinitialisations,
        "wall_time_s": run.wall_time_s,
        "sequence_duration_s": run.sequence_duration_s,
        "real_time_factor": run.real_time_factor,
        "cpu_time_s": run.cpu_time_s,
        "cpu_real_time_factor": run.cpu_real_time_factor,
        "image_load_cpu_s": run.image_load_cpu_s,
        "imu_samples": run.imu_samples,
        "map_lines": run.map_line_count,
        "map_line_candidates": run.map_line_candidates,
        "reidentified_lines": run.reidentified_lines,
    }
    if run.line_adjustment is not None:
        summary["line_adjustment"] = dict(run.line_adjustment)
    if run.time_offset_estimated:
        summary["time_offset_ms"] = 1e3 * run.time_offset_s
    if run.extrinsics_estimated:
        summary["extrinsics_correction"] = extrinsics_correction(run.extrinsics_correction)
    if run.stereo_correction_estimated:
        summary["stereo_correction"] = extrinsics_correction(run.stereo_correction, "S")
    if run.loop_enabled:
        loops = run.loops
        summary["loop_closure"] = {
            "loops": len(loops),
            "largest_correction_m": max((e["correction_m"] for e in loops), default=0.0),
            **run.loop_stats,
            "events": [{"t_new_s": 1e-9 * e["t_new_ns"], "t_old_s": 1e-9 * e["t_old_ns"], "inliers": e["inliers"],
                        "correction_m": e["correction_m"], "correction_yaw_deg": e["correction_yaw_deg"],
                        "T_old_new": e["T_old_new"].tolist(), "sigma_m": e["sigma_m"],
                        "sigma_yaw_deg": e["sigma_yaw_deg"], "method": e["method"]}
                       for e in loops]}
    gt = find_ground_truth(dataset) if dataset is not None else None
    traj = run.trajectory(True)
    if gt is not None and len(traj["t_ns"]) >= 3:
        from linnet import evaluation

        est = evaluation.trajectory_from_arrays(traj["t_ns"], traj["position"],
                                                traj["quaternion_xyzw"][:, [3, 0, 1, 2]], name="estimate")
        gt_traj = evaluation.load_trajectory(gt)
        try:
            res = evaluation.ape(est, gt_traj, align="se3", t_max_diff=0.01)
            summary["ape"] = {"rmse_m": res.rmse, "mean_m": res.mean, "median_m": res.median, "max_m": res.max,
                              "pairs": res.pairs, "align": "se3"}
            summary["path_length_m"] = evaluation.path_length(est)
            summary["gt_path_length_m"] = evaluation.path_length(res.reference)
        except Exception as e:  # report, don't lose the run
            summary["ape_error"] = str(e)
    return summary


#: A run fails when fewer than this fraction of its processed frames have a pose.
MIN_POSE_FRACTION = 0.5
#: Median points tracked per frame below which the images are the likely cause of a failure.
FEW_POINTS = 15
#: Median stereo matches per frame below which cam1's calibration is the likely cause.
FEW_STEREO = 10


def diagnose(run: "_linnet.RunSummary") -> tuple:
    """("ok", []) or ("failed", reasons): a run fails when it never initialised or fewer than MIN_POSE_FRACTION of
    its processed frames have a pose. The reasons are judged from what the front-end delivered."""
    results = run.results()
    if run.frames == 0:
        return "failed", ["no frame was run"]
    if run.processed_frames == 0:
        return "failed", [f"none of the {run.frames} frames was processed ({run.dropped_frames} dropped): the IMU "
                          "samples do not cover the image time stamps (same clock, both in ns?)"]
    if run.frames_with_pose >= MIN_POSE_FRACTION * run.processed_frames:
        return "ok", []
    points = _median([r.tracked_points for r in results])
    stereo = _median([r.stereo_points for r in results])
    head = ("never initialised" if run.frames_with_pose == 0 else
            f"only {run.frames_with_pose} of {run.processed_frames} frames have a pose")
    if not run.stereo:
        why = "monocular + IMU initialisation is not available yet: run a stereo dataset (cam0 and cam1)"
    elif points < FEW_POINTS:
        why = (f"too few points tracked (median {points:.0f} per frame): black, blank or badly exposed images, "
               "or images that do not match the calibration's resolution")
    elif stereo < FEW_STEREO:
        why = (f"too few stereo matches (median {stereo:.0f} of {points:.0f} tracked points): check cam1's "
               "calibration (intrinsics, distortion, the cam0-cam1 extrinsics)")
    else:
        why = (f"points are tracked (median {points:.0f}, {stereo:.0f} in stereo) but the estimator did not "
               "initialise or keep track: static data, or an IMU that does not agree with the images (time "
               "stamps, units, camera-IMU extrinsics)")
    return "failed", [f"{head}: {why}"]


def _median(values: List[float]) -> float:
    if not values:
        return 0.0
    v = sorted(values)
    return float(v[len(v) // 2]) if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])


def write_outputs(run: "_linnet.RunSummary", summary: dict, out: PathLike) -> None:
    out = Path(out)
    run.write(str(out))
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
