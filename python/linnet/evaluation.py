"""Trajectory evaluation: loading TUM / EuRoC trajectories, APE, RPE and path length.

The association of time stamps, the Umeyama alignment (Umeyama, "Least-squares estimation of transformation
parameters between two point patterns", TPAMI 1991) and the error metrics are evo's (Grupp, "evo: Python package for
the evaluation of odometry and SLAM", 2017); this module only reads files with precise error messages, converts
between Linnet's conventions and evo's, and packs the results into small dataclasses.

Conventions (DESIGN A3): time stamps int64 nanoseconds, positions in metres, Hamilton quaternions stored w, x, y, z.
File formats:
  * TUM: ``t x y z qx qy qz qw`` separated by white space, ``t`` in seconds, quaternion order x, y, z, w. Files whose
    time stamps are in ms, us or ns are read by the magnitude of the first one (linnet.timeunits).
  * EuRoC csv: ``t_ns, px, py, pz, qw, qx, qy, qz`` (8 columns) optionally followed by velocity and gyroscope /
    accelerometer biases (17 columns), comma separated, quaternion order w, x, y, z. A time with a decimal point is
    read by its magnitude, like TUM's.
Lines starting with ``#`` and blank lines are ignored. The format is detected from the first data line: commas mean
EuRoC csv, white space with 8 fields means TUM.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Union

import numpy as np

from linnet import timeunits
from linnet.fileio import InputError, read_text_file, write_json_file

__all__ = [
    "InputError",
    "Trajectory",
    "ErrorResult",
    "trajectory_from_arrays",
    "load_trajectory",
    "dataset_ground_truth",
    "detect_format",
    "ape",
    "rpe",
    "path_length",
    "time_slice",
    "POSE_RELATIONS",
    "ALIGNMENTS",
]


#: Accepted ``pose_relation`` names (the evo command line's names) -> evo's PoseRelation member name.
POSE_RELATIONS = {
    "trans_part": "translation_part",
    "full": "full_transformation",
    "rot_part": "rotation_part",
    "angle_deg": "rotation_angle_deg",
    "angle_rad": "rotation_angle_rad",
    "point_distance": "point_distance",
}

#: Accepted ``align`` values.
ALIGNMENTS = ("se3", "sim3", "none")

_EUROC_COLUMNS = (8, 17)
_TUM_COLUMNS = 8
_QUAT_MIN_NORM = 1e-6  # quaternions shorter than this are rejected as malformed


@dataclass(frozen=True)
class Trajectory:
    """A timed sequence of poses T_W_B.

    t_ns: (N,) int64 time stamps in ns, strictly increasing. positions: (N, 3) p_W of the body in metres.
    quaternions_wxyz: (N, 3+1) unit Hamilton quaternions of R_W_B, order w, x, y, z. name: for messages and plots.
    """

    t_ns: np.ndarray
    positions: np.ndarray
    quaternions_wxyz: np.ndarray
    name: str = ""

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    @property
    def t_s(self) -> np.ndarray:
        """Time stamps in seconds (float64)."""
        return self.t_ns.astype(np.float64) * 1e-9

    @property
    def duration_s(self) -> float:
        return float(self.t_ns[-1] - self.t_ns[0]) * 1e-9 if len(self) else 0.0

    def to_evo(self):
        """This trajectory as an ``evo.core.trajectory.PoseTrajectory3D`` (time in seconds, quaternions w, x, y, z)."""
        from evo.core.trajectory import PoseTrajectory3D

        traj = PoseTrajectory3D(
            positions_xyz=np.array(self.positions, dtype=np.float64),
            orientations_quat_wxyz=np.array(self.quaternions_wxyz, dtype=np.float64),
            timestamps=self.t_s,
        )
        traj.name = self.name
        return traj


PathLike = Union[str, Path]
TrajectoryLike = Union[Trajectory, str, Path]


def trajectory_from_arrays(t_ns, positions, quaternions_wxyz, name: str = "<arrays>") -> Trajectory:
    """Build a validated Trajectory from arrays: t_ns (N,) integer ns, positions (N, 3) m, quaternions (N, 4) w, x, y, z.

    Quaternions are normalised; raises InputError on wrong shapes, non-finite values, zero quaternions or time stamps
    that are not strictly increasing (naming the first offending index).
    """
    t = np.asarray(t_ns)
    p = np.asarray(positions, dtype=np.float64)
    q = np.asarray(quaternions_wxyz, dtype=np.float64)
    if t.ndim != 1:
        raise InputError(f"{name}: t_ns must be one-dimensional, got shape {t.shape}")
    n = t.shape[0]
    if p.shape != (n, 3):
        raise InputError(f"{name}: positions must have shape ({n}, 3), got {p.shape}")
    if q.shape != (n, 4):
        raise InputError(f"{name}: quaternions_wxyz must have shape ({n}, 4), got {q.shape}")
    if n > 0 and not np.issubdtype(t.dtype, np.integer):
        if not np.all(np.isfinite(t)) or np.any(t != np.round(t)):
            raise InputError(f"{name}: t_ns must hold integer nanoseconds")
    t = t.astype(np.int64)
    bad = np.flatnonzero(~np.all(np.isfinite(p), axis=1) | ~np.all(np.isfinite(q), axis=1))
    if bad.size:
        raise InputError(f"{name}: non-finite value in pose {bad[0]}")
    norms = np.linalg.norm(q, axis=1)
    bad = np.flatnonzero(norms < _QUAT_MIN_NORM)
    if bad.size:
        raise InputError(f"{name}: zero quaternion in pose {bad[0]}")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise InputError(
            f"{name}: time stamps must be strictly increasing, pose {bad[0] + 1} ({t[bad[0] + 1]} ns) "
            f"follows {t[bad[0]]} ns"
        )
    return Trajectory(t, p, q / norms[:, None], name)


# ------------------------------------------------------------------------------------------------------------- files


def _data_lines(path: Path):
    """Yield (line number, stripped text) for every non-comment, non-blank line."""
    text = read_text_file(path, "a trajectory file")
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if line and not line.startswith("#"):
            yield number, line


def detect_format(path: PathLike) -> str:
    """Return "tum" or "euroc" for a trajectory file, judged from its first data line."""
    path = Path(path)
    for number, line in _data_lines(path):
        return _format_of_line(path, number, line)
    raise InputError(f"{path}: no poses (the file is empty or holds only comments)")


def _format_of_line(path: Path, number: int, line: str) -> str:
    if "," in line:
        n = len(line.split(","))
        if n not in _EUROC_COLUMNS:
            raise InputError(
                f"{path}:{number}: comma-separated line with {n} columns; EuRoC csv needs 8 "
                "(t_ns, p xyz, q wxyz) or 17 (+ v, b_w, b_a)"
            )
        return "euroc"
    n = len(line.split())
    if n != _TUM_COLUMNS:
        raise InputError(f"{path}:{number}: {n} fields; a TUM line is 't x y z qx qy qz qw' (8 fields)")
    return "tum"


def _time_scale(path: Path, number: int, line: str, fmt: str) -> int:
    """ns per time unit of the file, from its first data line: TUM by the magnitude of the first time stamp (s, ms,
    us or ns, see linnet.timeunits); EuRoC csv in integer ns unless the time has a decimal point (then by magnitude)."""
    token = (line.split(",")[0] if fmt == "euroc" else line.split()[0]).strip()
    if fmt == "euroc" and "." not in token and "e" not in token.lower():
        return 1
    try:
        first = float(token)
    except ValueError:
        raise InputError(f"{path}:{number}: bad time stamp '{token}'") from None
    return timeunits.unit_of(first)[1]


def _parse_floats(path: Path, number: int, tokens) -> list:
    try:
        values = [float(tok) for tok in tokens]
    except ValueError:
        bad = next(tok for tok in tokens if not _is_float(tok))
        raise InputError(f"{path}:{number}: '{bad}' is not a number") from None
    if not all(math.isfinite(v) for v in values):
        raise InputError(f"{path}:{number}: non-finite value")
    return values


def _is_float(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def dataset_ground_truth(dataset: PathLike) -> Path:
    """mav0/state_groundtruth_estimate0/data.csv of a EuRoC-format dataset given as the folder holding mav0/ or as
    mav0/ itself. Raises InputError naming the file when it is missing."""
    dataset = Path(dataset)
    root = dataset
    if not (dataset / "mav0").is_dir() and dataset.name == "mav0":
        root = dataset.parent
    gt = root / "mav0" / "state_groundtruth_estimate0" / "data.csv"
    if not gt.is_file():
        raise InputError(f"{gt}: no such file (the dataset's ground truth)")
    return gt


def load_trajectory(path: PathLike, fmt: str = "auto") -> Trajectory:
    """Load a TUM or EuRoC csv trajectory (``fmt`` "auto", "tum" or "euroc"). Raises InputError naming file and line."""
    path = Path(path)
    if fmt not in ("auto", "tum", "euroc"):
        raise ValueError(f"fmt must be 'auto', 'tum' or 'euroc', got '{fmt}'")
    t_ns, pos, quat = [], [], []
    columns = None
    prev = None
    scale = None  # ns per file time unit, from the first line (linnet.timeunits)
    for number, line in _data_lines(path):
        if fmt == "auto":
            fmt = _format_of_line(path, number, line)
        if scale is None:
            scale = _time_scale(path, number, line, fmt)
        if fmt == "euroc":
            tokens = [tok.strip() for tok in line.split(",")]
            if columns is None:
                columns = len(tokens)
            if len(tokens) != columns or columns not in _EUROC_COLUMNS:
                raise InputError(
                    f"{path}:{number}: {len(tokens)} columns, expected {columns if columns in _EUROC_COLUMNS else 8}"
                    " (EuRoC csv: t_ns, px, py, pz, qw, qx, qy, qz[, v, b_w, b_a])"
                )
            t = timeunits.parse_time_ns(path, number, tokens[0], scale)
            v = _parse_floats(path, number, tokens[1:8])
            p, q = v[0:3], v[3:7]  # file order w, x, y, z
        else:
            tokens = line.split()
            if len(tokens) != _TUM_COLUMNS:
                raise InputError(f"{path}:{number}: {len(tokens)} fields, expected 8 (TUM: t x y z qx qy qz qw)")
            t = timeunits.parse_time_ns(path, number, tokens[0], scale)
            v = _parse_floats(path, number, tokens[1:8])
            p, q = v[0:3], [v[6], v[3], v[4], v[5]]  # file order x, y, z, w -> w, x, y, z
        if math.sqrt(sum(c * c for c in q)) < _QUAT_MIN_NORM:
            raise InputError(f"{path}:{number}: zero quaternion")
        if prev is not None and t <= prev[0]:
            raise InputError(
                f"{path}:{number}: time stamp {t} ns is not after the previous pose's {prev[0]} ns (line {prev[1]})"
            )
        prev = (t, number)
        t_ns.append(t)
        pos.append(p)
        quat.append(q)
    if not t_ns:
        raise InputError(f"{path}: no poses (the file is empty or holds only comments)")
    return trajectory_from_arrays(np.array(t_ns, dtype=np.int64), pos, quat, name=str(path))


def _as_trajectory(traj: TrajectoryLike) -> Trajectory:
    if isinstance(traj, Trajectory):
        return traj
    if isinstance(traj, (str, Path)):
        return load_trajectory(traj)
    raise TypeError(f"expected a Trajectory or a file path, got {type(traj).__name__}")


def time_slice(traj: Trajectory, t0_ns: int, t1_ns: int) -> Trajectory:
    """The poses of `traj` with t0_ns <= t <= t1_ns (e.g. the ground truth over an estimate's time span)."""
    keep = (traj.t_ns >= t0_ns) & (traj.t_ns <= t1_ns)
    return Trajectory(traj.t_ns[keep], traj.positions[keep], traj.quaternions_wxyz[keep], traj.name)


def path_length(traj: TrajectoryLike) -> float:
    """Length of the polyline through the positions, in metres."""
    p = _as_trajectory(traj).positions
    if p.shape[0] < 2:
        return 0.0
    return float(np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1)))


# ----------------------------------------------------------------------------------------------------------- metrics


@dataclass
class ErrorResult:
    """Statistics and per-pair data of an APE or RPE evaluation.

    Statistics are in ``unit`` (m for translation relations). ``t_ns`` / ``errors``: the time stamp (of the
    estimate; for RPE the pair's second pose) and the error of each pair. ``estimate`` is the associated estimate after
    alignment, ``reference`` the associated ground truth (same length, pairwise). ``alignment`` is the similarity
    (rotation 3x3, translation 3, scale) that was applied to the estimate: p_gt ~ s R p_est + t.
    """

    metric: str  # "ape" or "rpe"
    pose_relation: str
    align: str
    unit: str
    rmse: float
    mean: float
    median: float
    std: float
    min: float
    max: float
    pairs: int
    t_ns: np.ndarray
    errors: np.ndarray
    estimate: Trajectory
    reference: Trajectory
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    translation: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: float = 1.0
    t_max_diff_s: float = 0.0
    delta: float | None = None  # RPE only
    delta_unit: str | None = None  # RPE only: "m" or "frames"

    def stats(self) -> dict:
        """The numbers as a JSON-ready dict (no arrays except the 3x3 / 3-vector alignment)."""
        out = {
            "metric": self.metric,
            "pose_relation": self.pose_relation,
            "align": self.align,
            "unit": self.unit,
            "rmse": self.rmse,
            "mean": self.mean,
            "median": self.median,
            "std": self.std,
            "min": self.min,
            "max": self.max,
            "pairs": self.pairs,
            "t_max_diff_s": self.t_max_diff_s,
            "alignment": {
                "rotation": self.rotation.tolist(),
                "translation": self.translation.tolist(),
                "scale": self.scale,
            },
        }
        if self.metric == "rpe":
            out["delta"] = self.delta
            out["delta_unit"] = self.delta_unit
        return out


def _check_choice(value: str, allowed, what: str) -> None:
    if value not in allowed:
        raise ValueError(f"{what} must be one of {', '.join(allowed)}; got '{value}'")


def _associate(est: Trajectory, gt: Trajectory, t_max_diff: float):
    """Pairs of poses within t_max_diff seconds (evo's nearest-time association) as evo trajectories + ns stamps."""
    from evo.core import sync

    if not (t_max_diff >= 0.0 and math.isfinite(t_max_diff)):
        raise ValueError(f"t_max_diff must be a finite number >= 0 s, got {t_max_diff}")
    evo_gt, evo_est = gt.to_evo(), est.to_evo()
    try:
        evo_gt, evo_est = sync.associate_trajectories(evo_gt, evo_est, max_diff=t_max_diff)
    except sync.SyncException:
        raise InputError(
            f"no time stamps of {est.name or 'the estimate'} ({est.t_s[0]:.3f}..{est.t_s[-1]:.3f} s) and "
            f"{gt.name or 'the ground truth'} ({gt.t_s[0]:.3f}..{gt.t_s[-1]:.3f} s) within {t_max_diff} s of each other"
        ) from None
    # evo keeps the float stamps of the originals: map them back to the exact ns of each trajectory.
    t_est = est.t_ns[np.searchsorted(est.t_s, evo_est.timestamps)]
    t_gt = gt.t_ns[np.searchsorted(gt.t_s, evo_gt.timestamps)]
    return evo_est, evo_gt, t_est, t_gt


def _align(evo_est, evo_gt, align: str):
    """Align evo_est onto evo_gt in place; returns (R, t, s)."""
    from evo.core.geometry import GeometryException

    if align == "none":
        return np.eye(3), np.zeros(3), 1.0
    if evo_est.num_poses < 3:
        raise InputError(f"{align} alignment needs at least 3 associated poses, got {evo_est.num_poses}")
    try:
        r, t, s = evo_est.align(evo_gt, correct_scale=(align == "sim3"))
    except GeometryException as e:
        raise InputError(f"{align} alignment failed: {e}") from None
    return np.asarray(r), np.asarray(t), float(s)


def _from_evo(evo_traj, t_ns: np.ndarray, name: str) -> Trajectory:
    return Trajectory(
        np.array(t_ns, dtype=np.int64),
        np.array(evo_traj.positions_xyz, dtype=np.float64),
        np.array(evo_traj.orientations_quat_wxyz, dtype=np.float64),
        name,
    )


def _pose_relation(name: str):
    from evo.core import metrics

    _check_choice(name, tuple(POSE_RELATIONS), "pose_relation")
    return getattr(metrics.PoseRelation, POSE_RELATIONS[name])


def _result(metric, metric_name, pose_relation, align, rta, t_max_diff, t_err, est, gt, **extra) -> ErrorResult:
    from evo.core.metrics import StatisticsType as S

    st = {k: float(metric.get_statistic(getattr(S, k))) for k in ("rmse", "mean", "median", "std", "min", "max")}
    return ErrorResult(
        metric=metric_name,
        pose_relation=pose_relation,
        align=align,
        unit=metric.unit.value,
        pairs=int(len(metric.error)),
        t_ns=np.asarray(t_err, dtype=np.int64),
        errors=np.array(metric.error, dtype=np.float64),
        estimate=est,
        reference=gt,
        rotation=rta[0],
        translation=rta[1],
        scale=rta[2],
        t_max_diff_s=float(t_max_diff),
        **st,
        **extra,
    )


def ape(
    est: TrajectoryLike,
    gt: TrajectoryLike,
    align: str = "se3",
    t_max_diff: float = 0.01,
    pose_relation: str = "trans_part",
) -> ErrorResult:
    """Absolute pose error of ``est`` against ``gt`` (Trajectory objects or file paths).

    align: "se3" (rigid Umeyama), "sim3" (with scale, for monocular estimates) or "none". t_max_diff: largest time
    difference (s) of an associated pair. pose_relation: one of POSE_RELATIONS ("trans_part" = position error, m).
    Equivalent to ``evo_ape tum GT EST --t_max_diff T --pose_relation R [-a | -as]``.
    """
    from evo.core import metrics

    _check_choice(align, ALIGNMENTS, "align")
    relation = _pose_relation(pose_relation)
    est, gt = _as_trajectory(est), _as_trajectory(gt)
    evo_est, evo_gt, t_est, t_gt = _associate(est, gt, t_max_diff)
    rta = _align(evo_est, evo_gt, align)
    metric = metrics.APE(relation)
    metric.process_data((evo_gt, evo_est))
    aligned = _from_evo(evo_est, t_est, est.name)
    reference = _from_evo(evo_gt, t_gt, gt.name)
    return _result(metric, "ape", pose_relation, align, rta, t_max_diff, t_est, aligned, reference)


def rpe(
    est: TrajectoryLike,
    gt: TrajectoryLike,
    delta: float = 1.0,
    delta_unit: str = "m",
    align: str = "se3",
    t_max_diff: float = 0.01,
    pose_relation: str = "trans_part",
    all_pairs: bool = False,
) -> ErrorResult:
    """Relative pose error over pose pairs ``delta`` apart (``delta_unit`` "m" of travelled path, or "frames").

    Pairs are consecutive (non-overlapping) unless ``all_pairs``; each error's time stamp is the pair's second pose.
    Alignment only matters for "sim3" (scale); RPE is invariant to a rigid transformation of the estimate.
    Equivalent to ``evo_rpe tum GT EST --delta D --delta_unit m|f ...``.
    """
    from evo import EvoException
    from evo.core import metrics
    from evo.core.units import Unit

    _check_choice(align, ALIGNMENTS, "align")
    _check_choice(delta_unit, ("m", "frames"), "delta_unit")
    relation = _pose_relation(pose_relation)
    if not (delta > 0 and math.isfinite(delta)):
        raise ValueError(f"delta must be a positive number, got {delta}")
    unit = Unit.meters if delta_unit == "m" else Unit.frames
    if unit == Unit.frames and float(delta) != int(delta):
        raise ValueError(f"delta in frames must be an integer, got {delta}")
    est, gt = _as_trajectory(est), _as_trajectory(gt)
    evo_est, evo_gt, t_est, t_gt = _associate(est, gt, t_max_diff)
    rta = _align(evo_est, evo_gt, align)
    # Deltas the run cannot fit: one clear sentence rather than evo's message about an empty index list.
    travelled = float(evo_gt.path_length)
    if unit == Unit.meters and travelled <= delta:
        raise InputError(f"the ground truth travels {travelled:.3f} m over the estimate's span, not more than the RPE "
                         f"delta {delta:g} m: choose a smaller delta")
    if unit == Unit.frames and evo_est.num_poses <= delta:
        raise InputError(f"the run has {evo_est.num_poses} associated poses, not more than the RPE delta {delta:g} "
                         "frames: choose a smaller delta")
    metric = metrics.RPE(relation, delta=delta, delta_unit=unit, all_pairs=all_pairs)
    try:
        metric.process_data((copy.deepcopy(evo_gt), copy.deepcopy(evo_est)))
    except EvoException as e:
        raise InputError(f"RPE with delta {delta:g} {delta_unit}: {e}") from None
    aligned = _from_evo(evo_est, t_est, est.name)
    reference = _from_evo(evo_gt, t_gt, gt.name)
    t_err = t_est[np.asarray(metric.delta_ids, dtype=np.int64)]
    return _result(
        metric, "rpe", pose_relation, align, rta, t_max_diff, t_err, aligned, reference,
        delta=float(delta), delta_unit=delta_unit,
    )
