"""3D view of a run folder with rerun (optional dependency ``rerun-sdk``: ``pip install 'linnet[viewer]'``).

Shows the estimated trajectory, the ground truth (SE3-aligned into the estimate's world frame, so that the map stays
where it was built), the point-and-line map (``map.ply``) and the body pose over time. ``save`` writes a ``.rrd`` file
(headless); otherwise a rerun viewer is spawned.

Run folder (written by ``linnet run``): ``trajectory.tum`` (or ``trajectory.csv``), optional ``map.ply`` (ASCII PLY:
vertices x y z [red green blue], optional edges vertex1 vertex2 = line segments), optional ``map_lines.csv`` (the line
map, see ``linnet.map_eval``; its segments are shown when map.ply has no edges), optional ``summary.json`` whose
``dataset`` names a EuRoC folder with ground truth.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np

from linnet import evaluation as ev

__all__ = ["ViewerOptions", "MapGeometry", "RunView", "RerunMissing", "read_ply", "load_run", "log_run", "show_run"]


class RerunMissing(RuntimeError):
    """rerun-sdk is not installed."""


@dataclass
class ViewerOptions:
    """What to log and how it looks."""

    max_poses_over_time: int = 2000  # body poses logged on the time line (evenly subsampled), count
    trajectory_radius_m: float = 0.01  # line width of the trajectories, metres
    point_radius_m: float = 0.02  # map point size, metres
    segment_radius_m: float = 0.008  # map line width, metres
    axes_length_m: float = 0.3  # body axes length, metres
    t_max_diff_s: float = 0.02  # association tolerance for the ground-truth alignment, seconds

    def visit(self, visitor) -> None:
        visitor("max_poses_over_time", self.max_poses_over_time, "count")
        visitor("trajectory_radius_m", self.trajectory_radius_m, "metres")
        visitor("point_radius_m", self.point_radius_m, "metres")
        visitor("segment_radius_m", self.segment_radius_m, "metres")
        visitor("axes_length_m", self.axes_length_m, "metres")
        visitor("t_max_diff_s", self.t_max_diff_s, "seconds")


@dataclass
class MapGeometry:
    """Map points (N, 3) and line segments (M, 2, 3) in W, metres; colours uint8 RGB or None."""

    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    point_colors: Optional[np.ndarray] = None
    segments: np.ndarray = field(default_factory=lambda: np.zeros((0, 2, 3)))
    segment_colors: Optional[np.ndarray] = None


@dataclass
class RunView:
    """Everything shown for one run folder."""

    estimate: ev.Trajectory
    ground_truth: Optional[ev.Trajectory] = None  # in the estimate's world frame (aligned)
    ape_rmse_m: Optional[float] = None
    map: Optional[MapGeometry] = None
    notes: list = field(default_factory=list)  # why something is missing


def read_ply(path) -> MapGeometry:
    """Read an ASCII PLY of points and edges (Linnet's map format). Raises InputError naming file and line."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except FileNotFoundError:
        raise ev.InputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ev.InputError(f"{path}: cannot read as ASCII PLY ({e})") from None
    if not lines or lines[0].strip() != "ply":
        raise ev.InputError(f"{path}:1: not a PLY file (first line must be 'ply')")
    elements = []  # [name, count, [properties]]
    body = None
    for number, line in enumerate(lines[1:], start=2):
        f = line.split()
        if not f or f[0] in ("comment", "obj_info"):
            continue
        if f[0] == "format" and (len(f) < 2 or f[1] != "ascii"):
            raise ev.InputError(f"{path}:{number}: only ASCII PLY is supported, got '{line.strip()}'")
        elif f[0] == "element" and len(f) == 3 and f[2].isdigit():
            elements.append([f[1], int(f[2]), []])
        elif f[0] == "property" and elements and len(f) >= 3:
            elements[-1][2].append(f[-1])
        elif f[0] == "end_header":
            body = number
            break
        elif f[0] not in ("format",):
            raise ev.InputError(f"{path}:{number}: unexpected header line '{line.strip()}'")
    if body is None:
        raise ev.InputError(f"{path}: no end_header")
    rows = iter(enumerate(lines[body:], start=body + 1))
    data = {}
    for name, count, props in elements:
        table = np.empty((count, len(props)))
        for k in range(count):
            try:
                number, line = next(rows)
            except StopIteration:
                raise ev.InputError(f"{path}: truncated, element '{name}' has {k} of {count} rows") from None
            f = line.split()
            if len(f) != len(props):
                raise ev.InputError(f"{path}:{number}: {len(f)} values, element '{name}' has {len(props)}")
            try:
                table[k] = [float(x) for x in f]
            except ValueError:
                raise ev.InputError(f"{path}:{number}: not a number in '{line.strip()}'") from None
        data[name] = (table, props)
    return _map_from_tables(path, data)


def _map_from_tables(path: Path, data: dict) -> MapGeometry:
    if "vertex" not in data:
        return MapGeometry()
    vt, vprops = data["vertex"]
    try:
        xyz = vt[:, [vprops.index("x"), vprops.index("y"), vprops.index("z")]]
    except ValueError:
        raise ev.InputError(f"{path}: vertex element lacks x, y or z") from None
    rgb = None
    if all(c in vprops for c in ("red", "green", "blue")):
        rgb = vt[:, [vprops.index("red"), vprops.index("green"), vprops.index("blue")]].astype(np.uint8)
    used = np.zeros(len(xyz), dtype=bool)
    geometry = MapGeometry()
    if "edge" in data:
        et, eprops = data["edge"]
        idx = et[:, [eprops.index("vertex1"), eprops.index("vertex2")]].astype(np.int64)
        if idx.size and (idx.min() < 0 or idx.max() >= len(xyz)):
            raise ev.InputError(f"{path}: edge refers to a vertex outside 0..{len(xyz) - 1}")
        used[idx.ravel()] = True
        geometry.segments = xyz[idx]
        geometry.segment_colors = None if rgb is None else rgb[idx[:, 0]]
    geometry.points = xyz[~used]
    geometry.point_colors = None if rgb is None else rgb[~used]
    return geometry


def _find_trajectory(run_dir: Path) -> Path:
    for name in ("trajectory.tum", "trajectory.csv"):
        if (run_dir / name).is_file():
            return run_dir / name
    raise ev.InputError(f"{run_dir}: no trajectory.tum or trajectory.csv (is this a 'linnet run' output folder?)")


def _find_ground_truth(run_dir: Path) -> Optional[Path]:
    summary = run_dir / "summary.json"
    if not summary.is_file():
        return None
    try:
        dataset = json.loads(summary.read_text()).get("dataset")
    except (json.JSONDecodeError, AttributeError):
        return None
    if not dataset:
        return None
    for mav0 in (Path(dataset) / "mav0", Path(dataset)):
        gt = mav0 / "state_groundtruth_estimate0" / "data.csv"
        if gt.is_file():
            return gt
    return None


def _add_map_lines_csv(run_dir: Path, view: RunView) -> None:
    """Take the map segments from map_lines.csv when map.ply is missing or has no edges."""
    csv = run_dir / "map_lines.csv"
    if not csv.is_file() or (view.map is not None and len(view.map.segments)):
        return
    from linnet.map_eval import read_map_lines

    _ids, segments, _observations = read_map_lines(csv)
    if view.map is None:
        view.map = MapGeometry()
    view.map.segments = segments
    view.map.segment_colors = None
    view.notes.append("map lines read from map_lines.csv (map.ply has none)")


def load_run(run_dir, gt=None, options: Optional[ViewerOptions] = None) -> RunView:
    """Load a run folder; ``gt`` overrides the ground truth found through summary.json."""
    options = options or ViewerOptions()
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise ev.InputError(f"{run_dir}: not a folder")
    view = RunView(estimate=ev.load_trajectory(_find_trajectory(run_dir)))
    ply = run_dir / "map.ply"
    if ply.is_file():
        view.map = read_ply(ply)
    else:
        view.notes.append("no map.ply")
    _add_map_lines_csv(run_dir, view)
    gt_path = Path(gt) if gt is not None else _find_ground_truth(run_dir)
    if gt_path is None:
        view.notes.append("no ground truth (none given, none found through summary.json)")
        return view
    gt_traj = ev.load_trajectory(gt_path)
    try:
        res = ev.ape(view.estimate, gt_traj, align="se3", t_max_diff=options.t_max_diff_s)
    except ev.InputError as e:
        view.notes.append(f"ground truth not shown: {e}")
        return view
    # The alignment maps the estimate onto the ground truth (T_gt_est = [R t]); show the ground truth moved by its
    # inverse, in the estimate's frame, so that the map stays where it was built.
    from evo.core import lie_algebra

    evo_gt = gt_traj.to_evo()
    evo_gt.transform(lie_algebra.se3_inverse(lie_algebra.se3(res.rotation, res.translation)))
    view.ground_truth = ev.Trajectory(gt_traj.t_ns, np.array(evo_gt.positions_xyz),
                                      np.array(evo_gt.orientations_quat_wxyz), gt_traj.name)
    view.ape_rmse_m = res.rmse
    return view


def _rerun():
    try:
        import rerun
    except ImportError:
        raise RerunMissing("the 3D viewer needs rerun-sdk: pip install 'linnet[viewer]' (or: pip install rerun-sdk)") \
            from None
    return rerun


def log_run(view: RunView, rec, options: Optional[ViewerOptions] = None) -> None:
    """Log a RunView to the rerun RecordingStream ``rec`` (entities under world/)."""
    rr = _rerun()
    options = options or ViewerOptions()
    est = view.estimate
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    rec.log("world/estimate", rr.LineStrips3D([est.positions], radii=options.trajectory_radius_m,
                                              colors=[[40, 120, 220]]), static=True)
    if view.ground_truth is not None:
        label = "ground truth (SE3-aligned)"
        if view.ape_rmse_m is not None:
            label += f", APE RMSE {view.ape_rmse_m:.3f} m"
        rec.log("world/ground_truth", rr.LineStrips3D([view.ground_truth.positions], radii=options.trajectory_radius_m,
                                                      colors=[[150, 150, 150]], labels=[label]), static=True)
    if view.map is not None:
        m = view.map
        if len(m.points):
            rec.log("world/map/points", rr.Points3D(m.points, radii=options.point_radius_m,
                                                    colors=m.point_colors), static=True)
        if len(m.segments):
            rec.log("world/map/lines", rr.LineStrips3D(m.segments, radii=options.segment_radius_m,
                                                       colors=m.segment_colors), static=True)
    rec.log("world/body/axes", rr.Arrows3D(vectors=np.eye(3) * options.axes_length_m,
                                           colors=[[220, 40, 40], [40, 200, 40], [40, 40, 220]]), static=True)
    n = len(est)
    step = max(1, int(np.ceil(n / max(1, options.max_poses_over_time))))
    for i in range(0, n, step):
        rec.set_time("time", duration=float(est.t_ns[i] - est.t_ns[0]) * 1e-9)
        w, x, y, z = est.quaternions_wxyz[i]
        rec.log("world/body", rr.Transform3D(translation=est.positions[i], quaternion=rr.Quaternion(xyzw=[x, y, z, w])))


def show_run(view: RunView, save=None, options: Optional[ViewerOptions] = None, application_id: str = "linnet"):
    """Log ``view`` into a new recording: written to the .rrd file ``save``, or shown in a spawned viewer."""
    rr = _rerun()
    rec = rr.RecordingStream(application_id)
    if save is not None:
        Path(save).parent.mkdir(parents=True, exist_ok=True)
        rec.save(str(save))
    else:
        rec.spawn()
    log_run(view, rec, options)
    rec.flush()
    if save is not None:
        rec.disconnect()
    return rec
