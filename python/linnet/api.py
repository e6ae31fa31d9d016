"""High-level Python API: run a dataset, collect the outputs a user wants (files, summary, error)."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Callable, Optional, Union

from linnet import _linnet

PathLike = Union[str, Path]


def find_ground_truth(dataset: PathLike) -> Optional[Path]:
    """The ground-truth csv of a EuRoC folder (holding mav0/ or mav0 itself), or None."""
    root = Path(dataset)
    for mav0 in (root / "mav0", root):
        gt = mav0 / "state_groundtruth_estimate0" / "data.csv"
        if gt.is_file():
            return gt
    return None


def load_config(dataset: PathLike, config_file: Optional[PathLike] = None,
                overrides: Optional[str] = None) -> _linnet.Config:
    """Defaults + the dataset's calibration (sensor.yaml) + the keys of `config_file` + YAML `overrides` text."""
    cfg = _linnet.Config.for_euroc(str(dataset))
    if config_file is not None:
        cfg.merge(str(config_file))
    if overrides:
        cfg.merge_yaml(overrides, "<overrides>")
    return cfg


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


def summarize(run: "_linnet.RunSummary", dataset: PathLike) -> dict:
    """summary.json contents; the APE (SE3 alignment, position) when the dataset has ground truth."""
    summary = {
        "dataset": str(dataset),
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
    }
    gt = find_ground_truth(dataset)
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


def write_outputs(run: "_linnet.RunSummary", summary: dict, out: PathLike) -> None:
    out = Path(out)
    run.write(str(out))
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
