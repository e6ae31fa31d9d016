"""Evaluation of an estimated 3D line map against the simulator's true scene lines.

A run folder written by ``linnet run`` holds ``map_lines.csv``: one finite 3D segment per map line, in the estimator's
world frame W (metres), with the number of frames that observed it::

    #id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations
    12,0.1,0.2,0.3,1.1,0.2,0.3,17

A simulated dataset (``linnet simulate``) holds the true segments in ``sim/lines.csv``, in the ground-truth frame G of
``mav0/state_groundtruth_estimate0/data.csv``. W differs from G by a rigid transform T_G_W, which is found exactly as
the APE finds it: time-stamp association of the estimated trajectory with the ground truth and an SE3 Umeyama
alignment without scale (``linnet.evaluation.ape`` with ``align="se3"``; p_G = R p_W + t).

Metrics (``score_line_map``), for every evaluated map line with endpoints p0, p1 (after mapping into G):
  * association: the true segment j minimising (d_seg(p0, j) + d_seg(p1, j)) / 2, d_seg being the Euclidean distance
    of a point to the finite true segment (closest point clamped to the segment); ties go to the lowest index;
  * angle: the angle between the direction of the map segment and that of segment j, in degrees, in [0, 90] (the
    sign of a direction is irrelevant);
  * endpoint distances: the distances of p0 and p1 to the infinite line through segment j, metres.
Summary: the median angle, the median and 90th percentile of all 2 N endpoint distances, the fraction of map lines
whose two endpoint distances are both <= ``within_m``, and the coverage: how many true segments have such a map line.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Union

import numpy as np

from linnet import evaluation as ev
from linnet.evaluation import InputError, read_text_file

__all__ = [
    "MAP_LINES_COLUMNS",
    "LineMapScore",
    "read_map_lines",
    "read_true_lines",
    "score_line_map",
    "transform_segments",
    "evaluate_run_map",
]

PathLike = Union[str, Path]

#: Columns of map_lines.csv.
MAP_LINES_COLUMNS = ("id", "x0", "y0", "z0", "x1", "y1", "z1", "observations")

_MIN_SEGMENT_LENGTH_M = 1e-9  # shorter segments have no direction
_CHUNK_ELEMENTS = 1 << 19  # map-line x true-segment pairs per block of the association (a few MB per temporary)
_ROTATION_TOLERANCE = 1e-6  # |R^T R - I| and |det R - 1| accepted for T_gt_W


# ------------------------------------------------------------------------------------------------------------- files


def _read_text_lines(path: Path, what: str) -> list:
    return read_text_file(path, what, name_if_missing=True).splitlines()


def _parse_int(path: Path, number: int, token: str, column: str) -> int:
    try:
        return int(token)
    except ValueError:
        raise InputError(f"{path}:{number}: {column} '{token}' is not an integer") from None


def _parse_coordinates(path: Path, number: int, tokens) -> list:
    values = []
    for tok in tokens:
        try:
            v = float(tok)
        except ValueError:
            raise InputError(f"{path}:{number}: '{tok}' is not a number") from None
        if not math.isfinite(v):
            raise InputError(f"{path}:{number}: non-finite coordinate '{tok}'")
        values.append(v)
    return values


def read_map_lines(path: PathLike, with_sigma: bool = False) -> tuple:
    """Read a map_lines.csv: (ids (N,) int64, segments (N, 2, 3) float64 metres in W, observations (N,) int64).

    With ``with_sigma`` a fourth array (N,) holds each line's predicted endpoint standard deviation in metres (the
    11th column, endpoint_sigma; infinity where the file does not give it).

    Lines starting with ``#`` and blank lines are skipped; a file with only the header gives zero-length arrays.
    Raises InputError naming the file and line for a wrong column count, a value that is not a number (integers for
    id and observations), a non-finite coordinate, a negative observation count, a zero-length segment or a repeated
    id.
    """
    path = Path(path)
    ids, segments, observations, sigmas = [], [], [], []
    first_line_of_id = {}
    for number, raw in enumerate(_read_text_lines(path, "a map_lines.csv"), start=1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        tokens = [tok.strip() for tok in line.split(",")]
        sigma = math.inf
        if len(tokens) == len(MAP_LINES_COLUMNS) + 3:
            try:
                sigma = float(tokens[-1])
            except ValueError:
                raise InputError(f"{path}:{number}: endpoint_sigma '{tokens[-1]}' is not a number") from None
            if math.isnan(sigma) or sigma < 0.0:
                raise InputError(f"{path}:{number}: endpoint_sigma '{tokens[-1]}' is not a number >= 0")
        if len(tokens) in (len(MAP_LINES_COLUMNS) + 2, len(MAP_LINES_COLUMNS) + 3):
            tokens = tokens[:len(MAP_LINES_COLUMNS)]  # t_last [ns], triangulation_angle [deg]: not needed here
        if len(tokens) != len(MAP_LINES_COLUMNS):
            raise InputError(f"{path}:{number}: {len(tokens)} columns, expected {len(MAP_LINES_COLUMNS)} "
                             f"({','.join(MAP_LINES_COLUMNS)}), {len(MAP_LINES_COLUMNS) + 2} "
                             f"(with t_last,triangulation_angle) or {len(MAP_LINES_COLUMNS) + 3} (and endpoint_sigma)")
        line_id = _parse_int(path, number, tokens[0], "id")
        xyz = _parse_coordinates(path, number, tokens[1:7])
        obs = _parse_int(path, number, tokens[7], "observations")
        if obs < 0:
            raise InputError(f"{path}:{number}: negative observation count {obs}")
        if xyz[0:3] == xyz[3:6]:
            raise InputError(f"{path}:{number}: segment of map line {line_id} has zero length")
        if line_id in first_line_of_id:
            raise InputError(f"{path}:{number}: map line id {line_id} repeated (first on line "
                             f"{first_line_of_id[line_id]})")
        first_line_of_id[line_id] = number
        ids.append(line_id)
        segments.append([xyz[0:3], xyz[3:6]])
        observations.append(obs)
        sigmas.append(sigma)
    out = (np.array(ids, dtype=np.int64), np.array(segments, dtype=np.float64).reshape(-1, 2, 3),
           np.array(observations, dtype=np.int64))
    return out + (np.array(sigmas, dtype=np.float64),) if with_sigma else out


def read_true_lines(path: PathLike) -> np.ndarray:
    """The (M, 2, 3) true segments (metres, ground-truth frame) of a simulator's sim/lines.csv.

    Reads with ``linnet.sim.writer.read_lines_csv``; raises InputError naming the file when it is missing or
    malformed.
    """
    from linnet.sim.writer import read_lines_csv

    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such file (the true scene lines; only datasets written by 'linnet simulate' "
                         "have them)")
    try:
        segments, _kinds = read_lines_csv(path)
    except UnicodeDecodeError as e:  # before ValueError, its base class
        raise InputError(f"{path}: not a text file ({e.reason} at byte {e.start})") from None
    except (ValueError, IndexError) as e:
        raise InputError(f"{path}: malformed (expected rows 'id,x0,y0,z0,x1,y1,z1,kind'): {e}") from None
    except OSError as e:
        raise InputError(f"{path}: cannot read ({e.strerror})") from None
    if not np.all(np.isfinite(segments)):
        raise InputError(f"{path}: non-finite coordinate")
    return segments


# ----------------------------------------------------------------------------------------------------------- metrics


@dataclass
class LineMapScore:
    """Scores of map segments against true segments (see the module docstring for the definitions).

    Per evaluated map line i (arrays of length N = count): ``true_index[i]`` the associated true segment,
    ``association_dist_m[i]`` the mean distance of its endpoints to that finite segment, ``angle_deg[i]`` in [0, 90],
    ``endpoint_dist_m[i]`` (2,) the distances of its endpoints to the associated infinite true line; ``segments`` (N, 2,
    3) the map segments in the ground-truth frame. Summary statistics are NaN when count is 0.
    """

    true_index: np.ndarray
    association_dist_m: np.ndarray
    angle_deg: np.ndarray
    endpoint_dist_m: np.ndarray
    segments: np.ndarray
    within_m: float
    true_lines_total: int
    count: int = 0
    true_lines_associated: int = 0  # distinct true segments some map line is associated with
    true_lines_mapped: int = 0  # distinct true segments with an associated map line whose two endpoint distances
    # are both <= within_m (the map's coverage: how many physical lines it holds a good line of)
    median_angle_deg: float = math.nan
    median_endpoint_dist_m: float = math.nan  # over all 2 N endpoint distances
    p90_endpoint_dist_m: float = math.nan  # 90th percentile (linear interpolation) of all 2 N endpoint distances
    frac_within: float = math.nan  # fraction of map lines with both endpoint distances <= within_m
    median_association_dist_m: float = math.nan  # median of association_dist_m: far above the endpoint distances when
    # most map lines have no true segment (texture edges of the room and hall scenes, which sim/lines.csv lacks)

    def summary(self) -> dict:
        """The summary figures as a JSON-ready dict (NaN -> None)."""
        def number(x):
            return None if (isinstance(x, float) and not math.isfinite(x)) else x

        return {
            "count": self.count,
            "true_lines_total": self.true_lines_total,
            "true_lines_associated": self.true_lines_associated,
            "true_lines_mapped": self.true_lines_mapped,
            "median_angle_deg": number(self.median_angle_deg),
            "median_endpoint_dist_m": number(self.median_endpoint_dist_m),
            "p90_endpoint_dist_m": number(self.p90_endpoint_dist_m),
            "within_m": self.within_m,
            "frac_within": number(self.frac_within),
            "median_association_dist_m": number(self.median_association_dist_m),
        }


def _as_segments(segments, name: str) -> np.ndarray:
    s = np.asarray(segments, dtype=np.float64)
    if s.ndim != 3 or s.shape[1:] != (2, 3):
        raise ValueError(f"{name} must have shape (N, 2, 3), got {s.shape}")
    if not np.all(np.isfinite(s)):
        bad = np.flatnonzero(~np.all(np.isfinite(s), axis=(1, 2)))[0]
        raise ValueError(f"{name}: non-finite coordinate in segment {bad}")
    lengths = np.linalg.norm(s[:, 1] - s[:, 0], axis=1)
    short = np.flatnonzero(lengths < _MIN_SEGMENT_LENGTH_M)
    if short.size:
        raise ValueError(f"{name}: segment {short[0]} is shorter than {_MIN_SEGMENT_LENGTH_M:g} m (no direction)")
    return s


def _check_transform(T: np.ndarray) -> np.ndarray:
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"T_gt_W must be a 4x4 matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError("T_gt_W has non-finite entries")
    if not np.allclose(T[3], [0.0, 0.0, 0.0, 1.0], rtol=0.0, atol=1e-12):
        raise ValueError(f"T_gt_W's last row must be [0, 0, 0, 1], got {T[3].tolist()}")
    R = T[:3, :3]
    if (np.max(np.abs(R.T @ R - np.eye(3))) > _ROTATION_TOLERANCE
            or abs(np.linalg.det(R) - 1.0) > _ROTATION_TOLERANCE):
        raise ValueError("T_gt_W's upper-left 3x3 block is not a rotation (rigid transforms only, no scale)")
    return T


def transform_segments(T: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Segments (N, 2, 3) mapped by the 4x4 rigid transform T: p' = R p + t."""
    s = np.asarray(segments, dtype=np.float64)
    T = np.asarray(T, dtype=np.float64)
    return s @ T[:3, :3].T + T[:3, 3]


def _associate(map_segs: np.ndarray, true_segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For every map segment: the index of the true finite segment with the smallest mean endpoint distance, and
    that mean distance. Blocks of map segments keep the (block, M, 3) temporaries near _CHUNK_ELEMENTS x 3 doubles."""
    n, m = map_segs.shape[0], true_segs.shape[0]
    a = true_segs[:, 0]  # (M, 3)
    d = true_segs[:, 1] - a  # (M, 3)
    inv_len2 = 1.0 / np.einsum("mk,mk->m", d, d)
    best = np.empty(n, dtype=np.int64)
    best_dist = np.empty(n, dtype=np.float64)
    block = max(1, _CHUNK_ELEMENTS // max(1, m))
    for start in range(0, n, block):
        chunk = map_segs[start:start + block]
        total = np.zeros((chunk.shape[0], m))
        for e in range(2):
            w = chunk[:, e, None, :] - a[None]  # (B, M, 3): endpoint relative to each segment start
            t = np.clip(np.einsum("bmk,mk->bm", w, d) * inv_len2, 0.0, 1.0)
            w -= t[..., None] * d[None]  # endpoint minus its closest point on the finite segment
            total += np.sqrt(np.einsum("bmk,bmk->bm", w, w))
        idx = np.argmin(total, axis=1)  # first minimum: ties go to the lowest index
        best[start:start + chunk.shape[0]] = idx
        best_dist[start:start + chunk.shape[0]] = 0.5 * total[np.arange(chunk.shape[0]), idx]
    return best, best_dist


def score_line_map(segments_W, true_segments, T_gt_W: Optional[np.ndarray] = None,
                   within_m: float = 0.05) -> LineMapScore:
    """Score map segments (N, 2, 3), metres in W, against true segments (M, 2, 3) in the ground-truth frame.

    T_gt_W: 4x4 rigid transform mapping W into the ground-truth frame (None: the frames coincide). within_m: distance
    bound of ``frac_within``, metres. Filtering (e.g. by observation count) is the caller's. Raises ValueError on bad
    shapes, non-finite values, zero-length segments, a non-rigid T_gt_W, or map lines without any true segment.
    """
    if not (within_m >= 0.0 and math.isfinite(within_m)):
        raise ValueError(f"within_m must be a finite number >= 0 m, got {within_m}")
    segs = _as_segments(segments_W, "segments_W")
    truth = _as_segments(true_segments, "true_segments")
    if T_gt_W is not None:
        segs = transform_segments(_check_transform(T_gt_W), segs)
    n = segs.shape[0]
    if n and truth.shape[0] == 0:
        raise ValueError("no true segments to associate the map lines with")
    if n == 0:
        return LineMapScore(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros(0), np.zeros((0, 2)), segs,
                            float(within_m), int(truth.shape[0]))
    idx, assoc = _associate(segs, truth)
    a = truth[idx, 0]  # (N, 3)
    u = truth[idx, 1] - a
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = segs[:, 1] - segs[:, 0]
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    # atan2(|u x v|, |u . v|) is accurate for small angles too (acos is not) and lies in [0, 90] degrees.
    angle = np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=1), np.abs(np.einsum("nk,nk->n", u, v))))
    w = segs - a[:, None, :]  # (N, 2, 3)
    along = np.einsum("nek,nk->ne", w, u)
    perp = w - along[..., None] * u[:, None, :]
    dist = np.linalg.norm(perp, axis=2)  # (N, 2): endpoint distances to the infinite true line
    all_dist = dist.ravel()
    good = np.all(dist <= within_m, axis=1)
    return LineMapScore(
        true_index=idx,
        association_dist_m=assoc,
        angle_deg=angle,
        endpoint_dist_m=dist,
        segments=segs,
        within_m=float(within_m),
        true_lines_total=int(truth.shape[0]),
        count=int(n),
        true_lines_associated=int(np.unique(idx).size),
        true_lines_mapped=int(np.unique(idx[good]).size),
        median_angle_deg=float(np.median(angle)),
        median_endpoint_dist_m=float(np.median(all_dist)),
        p90_endpoint_dist_m=float(np.percentile(all_dist, 90.0)),
        frac_within=float(np.mean(good)),
        median_association_dist_m=float(np.median(assoc)),
    )


# -------------------------------------------------------------------------------------------------------------- runs


def _dataset_paths(dataset: Path) -> tuple[Path, Path]:
    """(ground truth data.csv, sim/lines.csv) of a dataset given as the folder holding mav0/ or as mav0/ itself."""
    if not dataset.is_dir():
        raise InputError(f"{dataset}: not a folder (expected a dataset folder holding mav0/ and sim/)")
    gt = ev.dataset_ground_truth(dataset)
    return gt, gt.parents[2] / "sim" / "lines.csv"  # beside mav0/


def _run_trajectory(run_dir: Path) -> Path:
    for name in ("trajectory.tum", "trajectory.csv"):
        if (run_dir / name).is_file():
            return run_dir / name
    raise InputError(f"{run_dir / 'trajectory.tum'}: no such file (the run's trajectory; is {run_dir} a "
                     "'linnet run' output folder?)")


def _json_number(x: float) -> Optional[float]:
    return None if not math.isfinite(x) else float(x)


def evaluate_run_map(run_dir: PathLike, dataset: PathLike, min_observations: int = 5, within_m: float = 0.05,
                     t_max_diff: float = 0.01, max_sigma_m: Optional[float] = None) -> dict:
    """Score RUN_DIR/map_lines.csv against DATASET/sim/lines.csv; returns a JSON-ready dict.

    The map lines observed by at least ``min_observations`` frames are mapped into the ground-truth frame by the SE3
    alignment (no scale) of RUN_DIR/trajectory.tum onto DATASET/mav0/state_groundtruth_estimate0/data.csv (time
    stamps associated within ``t_max_diff`` seconds, as ``linnet.evaluation.ape``) and scored by ``score_line_map``.
    With ``max_sigma_m`` only the lines whose predicted endpoint standard deviation (map_lines.csv's endpoint_sigma)
    is at most that many metres are scored (a file without that column then scores none).
    The dict holds the summary figures of LineMapScore.summary(), "lines_total", "lines_evaluated",
    "min_observations", the file names and "alignment" (T_gt_W's rotation and translation, the pose pairs and the
    APE RMSE of that alignment). Raises InputError naming the missing or malformed file.
    """
    run_dir, dataset = Path(run_dir), Path(dataset)
    if min_observations < 0:
        raise ValueError(f"min_observations must be >= 0, got {min_observations}")
    if max_sigma_m is not None and not max_sigma_m >= 0.0:
        raise ValueError(f"max_sigma_m must be >= 0 m, got {max_sigma_m}")
    if not run_dir.is_dir():
        raise InputError(f"{run_dir}: not a folder (expected a 'linnet run' output folder)")
    map_file = run_dir / "map_lines.csv"
    if not map_file.is_file():
        raise InputError(f"{map_file}: no such file (the run's line map)")
    traj_file = _run_trajectory(run_dir)
    gt_file, lines_file = _dataset_paths(dataset)
    _ids, segments, observations, sigmas = read_map_lines(map_file, with_sigma=True)
    true_segments = read_true_lines(lines_file)
    estimate = ev.load_trajectory(traj_file)
    ground_truth = ev.load_trajectory(gt_file)
    res = ev.ape(estimate, ground_truth, align="se3", t_max_diff=t_max_diff)
    T_gt_W = np.eye(4)
    T_gt_W[:3, :3] = res.rotation
    T_gt_W[:3, 3] = res.translation
    keep = observations >= min_observations
    if max_sigma_m is not None:
        keep &= sigmas <= max_sigma_m
    try:
        score = score_line_map(segments[keep], true_segments, T_gt_W=T_gt_W, within_m=within_m)
    except ValueError as e:
        raise InputError(f"{map_file} vs {lines_file}: {e}") from None
    out = {
        "run_dir": str(run_dir),
        "dataset": str(dataset),
        "map_lines": str(map_file),
        "true_lines": str(lines_file),
        "lines_total": int(segments.shape[0]),
        "lines_evaluated": score.count,
        "min_observations": int(min_observations),
        "max_sigma_m": None if max_sigma_m is None else float(max_sigma_m),
    }
    out.update(score.summary())
    out["alignment"] = {
        "align": "se3",
        "description": "p_gt = R p_W + t (maps the estimator's world frame W into the ground-truth frame)",
        "rotation": res.rotation.tolist(),
        "translation": res.translation.tolist(),
        "scale": 1.0,
        "pairs": res.pairs,
        "t_max_diff_s": float(t_max_diff),
        "ape_rmse_m": _json_number(res.rmse),
        "trajectory": str(traj_file),
        "ground_truth": str(gt_file),
    }
    return out
