"""Evaluation of a run's loop closures against the ground truth.

A run folder written by ``linnet run`` with loop closure on holds ``loops.csv``: one row per loop closed, with the
relative pose of the two keyframes' bodies as the loop closer measured it (T_old_new: the new keyframe's body in the
old one's), the sigmas of its pose-graph edge and how it was verified::

    #t_new [ns],t_old [ns],inliers,correction [m],correction_yaw [deg],x [m],y [m],z [m],qx,qy,qz,qw,sigma [m],
     sigma_yaw [deg],method

The true relative pose comes from a ground-truth trajectory of the same body (EuRoC's
``mav0/state_groundtruth_estimate0/data.csv``, or any file ``linnet.evaluation.load_trajectory`` reads), interpolated
at the two keyframes' time stamps (linear in position, spherical in rotation, between the two ground-truth samples
around each stamp; a stamp farther than ``t_max_diff`` from every sample is an error). Relative poses need no
alignment of the run's world frame with the ground truth's.

Per loop (``loop_errors``): the position error |p_measured - p_true| in metres, the rotation error (the angle of
R_true^T R_measured) in degrees, and the position error over the edge's sigma. Summaries (``summarise``) group the
loops by how they were verified and by their PnP inliers.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence, Union

import numpy as np

from linnet import evaluation as ev
from linnet.evaluation import InputError, read_text_file

__all__ = ["LOOPS_COLUMNS", "Loops", "read_loops", "loop_errors", "summarise", "evaluate_run_loops"]

PathLike = Union[str, Path]

#: Columns of loops.csv (the run's writer: cpp/src/pipeline/dataset_runner.cc).
LOOPS_COLUMNS = ("t_new", "t_old", "inliers", "correction", "correction_yaw", "x", "y", "z", "qx", "qy", "qz", "qw",
                 "sigma", "sigma_yaw", "method")

_QUATERNION_TOLERANCE = 1e-3  # |1 - |q|| accepted for a measured rotation


@dataclass(frozen=True)
class Loops:
    """The loops of a loops.csv, one entry per row (N rows).

    t_new_ns, t_old_ns: (N,) int64 keyframe stamps. inliers: (N,) int64. p: (N, 3) measured position of the new body in
    the old one's frame, metres. q_wxyz: (N, 4) measured unit rotation. sigma_m / sigma_yaw_deg: (N,) the edge's sigmas.
    methods: how each was verified ("descriptors", "guided", "lines", or what the file says).
    """

    t_new_ns: np.ndarray
    t_old_ns: np.ndarray
    inliers: np.ndarray
    p: np.ndarray
    q_wxyz: np.ndarray
    sigma_m: np.ndarray
    sigma_yaw_deg: np.ndarray
    methods: tuple

    def __len__(self) -> int:
        return int(self.t_new_ns.shape[0])


def _number(path: Path, number: int, token: str, column: str, integer: bool = False):
    try:
        value = int(token) if integer else float(token)
    except ValueError:
        raise InputError(f"{path}:{number}: {column} '{token}' is not {'an integer' if integer else 'a number'}") \
            from None
    if not integer and not math.isfinite(value):
        raise InputError(f"{path}:{number}: {column} '{token}' is not finite")
    return value


def read_loops(path: PathLike) -> Loops:
    """Read a loops.csv. Lines starting with ``#`` and blank lines are skipped; a file with only the header gives no
    loops. Raises InputError naming the file and line for a wrong column count, a value that is not a number, a
    rotation that is not a unit quaternion or a negative sigma, and naming the file when it is missing."""
    path = Path(path)
    t_new, t_old, inliers, p, q, sigma, sigma_yaw, methods = [], [], [], [], [], [], [], []
    for number, raw in enumerate(read_text_file(path, "a loops.csv", name_if_missing=True).splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        tokens = [tok.strip() for tok in line.split(",")]
        if len(tokens) != len(LOOPS_COLUMNS):
            raise InputError(f"{path}:{number}: {len(tokens)} columns, expected {len(LOOPS_COLUMNS)} "
                             f"({','.join(LOOPS_COLUMNS)})")
        t_new.append(_number(path, number, tokens[0], "t_new", integer=True))
        t_old.append(_number(path, number, tokens[1], "t_old", integer=True))
        inliers.append(_number(path, number, tokens[2], "inliers", integer=True))
        p.append([_number(path, number, tokens[k], LOOPS_COLUMNS[k]) for k in (5, 6, 7)])
        qx, qy, qz, qw = (_number(path, number, tokens[k], LOOPS_COLUMNS[k]) for k in (8, 9, 10, 11))
        norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
        if abs(norm - 1.0) > _QUATERNION_TOLERANCE:
            raise InputError(f"{path}:{number}: quaternion norm {norm:.4f} is not 1")
        q.append([qw / norm, qx / norm, qy / norm, qz / norm])
        for column, value, out in (("sigma", tokens[12], sigma), ("sigma_yaw", tokens[13], sigma_yaw)):
            v = _number(path, number, value, column)
            if v < 0.0:
                raise InputError(f"{path}:{number}: {column} {v} is negative")
            out.append(v)
        methods.append(tokens[14])
    return Loops(np.array(t_new, dtype=np.int64), np.array(t_old, dtype=np.int64), np.array(inliers, dtype=np.int64),
                 np.array(p, dtype=np.float64).reshape(-1, 3), np.array(q, dtype=np.float64).reshape(-1, 4),
                 np.array(sigma, dtype=np.float64), np.array(sigma_yaw, dtype=np.float64), tuple(methods))


def _rotation(q_wxyz: np.ndarray):
    from scipy.spatial.transform import Rotation

    return Rotation.from_quat(np.roll(np.atleast_2d(q_wxyz), -1, axis=1))


def _poses_at(gt: ev.Trajectory, t_ns: np.ndarray, t_max_diff: float, what: str):
    """Ground-truth rotations and positions at the stamps t_ns, interpolated between the samples around each."""
    from scipy.spatial.transform import Rotation

    t = gt.t_ns
    if len(t) < 2:
        raise InputError(f"{gt.name}: the ground truth needs at least 2 poses")
    after = np.clip(np.searchsorted(t, t_ns), 0, len(t) - 1)
    before = np.clip(after - 1, 0, len(t) - 1)
    nearest = np.minimum(np.abs(t[after] - t_ns), np.abs(t[before] - t_ns))
    far = np.nonzero(nearest > t_max_diff * 1e9)[0]
    if far.size:
        raise InputError(f"{gt.name}: no ground-truth pose within {t_max_diff:g} s of the {what} keyframe at "
                         f"{t_ns[far[0]]} ns (loop {far[0] + 1})")
    i = np.clip(np.searchsorted(t, t_ns, side="right") - 1, 0, len(t) - 2)
    u = np.clip((t_ns - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)
    positions = gt.positions[i] + u[:, None] * (gt.positions[i + 1] - gt.positions[i])
    R0, R1 = _rotation(gt.quaternions_wxyz[i]), _rotation(gt.quaternions_wxyz[i + 1])
    return R0 * Rotation.from_rotvec(u[:, None] * (R0.inv() * R1).as_rotvec()), positions


def loop_errors(loops: Loops, ground_truth: ev.Trajectory, t_max_diff: float = 0.01) -> dict:
    """Each loop's error against the ground truth: {"position_m": (N,), "rotation_deg": (N,), "sigmas": (N,)
    (position error over the edge's sigma; inf for a zero sigma), "true_p": (N, 3)}. Raises InputError when a keyframe
    stamp has no ground-truth pose within t_max_diff seconds."""
    n = len(loops)
    if n == 0:
        empty = np.zeros(0)
        return {"position_m": empty, "rotation_deg": empty, "sigmas": empty, "true_p": np.zeros((0, 3))}
    R_old, p_old = _poses_at(ground_truth, loops.t_old_ns, t_max_diff, "old")
    R_new, p_new = _poses_at(ground_truth, loops.t_new_ns, t_max_diff, "new")
    true_p = R_old.inv().apply(p_new - p_old)
    true_R = R_old.inv() * R_new
    position = np.linalg.norm(loops.p - true_p, axis=1)
    rotation = np.degrees((true_R.inv() * _rotation(loops.q_wxyz)).magnitude())
    with np.errstate(divide="ignore", invalid="ignore"):
        sigmas = np.where(loops.sigma_m > 0.0, position / loops.sigma_m, np.inf)
    return {"position_m": position, "rotation_deg": rotation, "sigmas": sigmas, "true_p": true_p}


def _inlier_band(inliers: int, bands: Sequence[int]) -> str:
    lower = 0
    for b in bands:
        if inliers < b:
            return f"{lower}-{b - 1}" if lower else f"< {b}"
        lower = b
    return f">= {lower}"


def _stats(position: np.ndarray, rotation: np.ndarray, sigmas: np.ndarray, sigma_m: np.ndarray) -> dict:
    finite = sigmas[np.isfinite(sigmas)]
    return {
        "loops": int(position.size),
        "position_rmse_m": float(np.sqrt(np.mean(position ** 2))),
        "position_median_m": float(np.median(position)),
        "position_max_m": float(np.max(position)),
        "rotation_rmse_deg": float(np.sqrt(np.mean(rotation ** 2))),
        "sigma_median_m": float(np.median(sigma_m)),
        "error_over_sigma_rms": float(np.sqrt(np.mean(finite ** 2))) if finite.size else None,
        "beyond_3_sigma": float(np.mean(sigmas > 3.0)),
    }


def summarise(loops: Loops, errors: dict, bands: Sequence[int] = (20, 30)) -> list:
    """Statistics of all loops, then of each (method, inlier band) group in order of method and band: a list of dicts
    with "method", "inliers" (the band, e.g. "20-29"), "loops", "position_rmse_m", "position_median_m",
    "position_max_m", "rotation_rmse_deg", "sigma_median_m", "error_over_sigma_rms" (RMS of the position error's norm
    over sigma: about sqrt(3) for well-calibrated isotropic sigmas) and "beyond_3_sigma" (fraction). ``bands``:
    increasing inlier counts that start a new band."""
    if list(bands) != sorted(set(bands)) or any(b <= 0 for b in bands):
        raise ValueError(f"bands must be increasing positive inlier counts, got {list(bands)}")
    if len(loops) == 0:
        return []
    pos, rot, sig = errors["position_m"], errors["rotation_deg"], errors["sigmas"]
    rows = [dict(method="all", inliers="all", **_stats(pos, rot, sig, loops.sigma_m))]
    band_of = [_inlier_band(int(n), bands) for n in loops.inliers]
    order = {name: k for k, name in enumerate([_inlier_band(0, bands)] +
                                              [_inlier_band(b, bands) for b in bands])}
    for method in sorted(set(loops.methods)):
        for band in sorted({b for b, m in zip(band_of, loops.methods) if m == method}, key=order.get):
            keep = np.array([m == method and b == band for m, b in zip(loops.methods, band_of)])
            rows.append(dict(method=method, inliers=band,
                             **_stats(pos[keep], rot[keep], sig[keep], loops.sigma_m[keep])))
    return rows


def _ground_truth_file(ground_truth: Path) -> Path:
    if ground_truth.is_dir():
        return ev.dataset_ground_truth(ground_truth)
    if not ground_truth.is_file():
        raise InputError(f"{ground_truth}: no such file or folder (a ground-truth trajectory or a dataset folder)")
    return ground_truth


def evaluate_run_loops(run_dir: PathLike, ground_truth: PathLike, t_max_diff: float = 0.01,
                       bands: Sequence[int] = (20, 30), worst: int = 5) -> dict:
    """Score RUN_DIR/loops.csv against a ground-truth trajectory file or a dataset folder (its
    mav0/state_groundtruth_estimate0/data.csv); returns a JSON-ready dict: "loops_file", "ground_truth",
    "groups" (``summarise``), "worst" (the ``worst`` loops by position error: stamps in ns, inliers, method, errors and
    sigma) and "loops" (every loop's errors, in file order). Raises InputError naming a missing or malformed file."""
    run_dir, ground_truth = Path(run_dir), Path(ground_truth)
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: not a folder (expected a 'linnet run' output folder)")
    if t_max_diff <= 0.0:
        raise ValueError(f"t_max_diff must be > 0 s, got {t_max_diff}")
    loops_file = run_dir / "loops.csv"
    loops = read_loops(loops_file)
    gt_file = _ground_truth_file(ground_truth)
    errors = loop_errors(loops, ev.load_trajectory(gt_file), t_max_diff=t_max_diff)

    def entry(k: int) -> dict:
        s = errors["sigmas"][k]
        return {"t_new_ns": int(loops.t_new_ns[k]), "t_old_ns": int(loops.t_old_ns[k]),
                "inliers": int(loops.inliers[k]), "method": loops.methods[k],
                "position_error_m": float(errors["position_m"][k]),
                "rotation_error_deg": float(errors["rotation_deg"][k]), "sigma_m": float(loops.sigma_m[k]),
                "error_over_sigma": float(s) if math.isfinite(s) else None}

    by_error = np.argsort(-errors["position_m"], kind="stable")[:max(0, worst)]
    return {"loops_file": str(loops_file), "ground_truth": str(gt_file), "t_max_diff_s": t_max_diff,
            "bands": list(bands), "groups": summarise(loops, errors, bands),
            "worst": [entry(int(k)) for k in by_error], "loops": [entry(k) for k in range(len(loops))]}
