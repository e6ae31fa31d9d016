"""Reading a simulated sequence back and projecting its ground-truth geometry into its frames, for scoring
front-ends (and for the simulator's own tests).

    truth = SequenceTruth.load("out/loop_room")            # a folder written by linnet simulate
    T_W_C = truth.camera_pose(t_ns, cam=0)
    px, ok = project_points(truth.points, T_W_C, truth.cameras[0], depth=None)
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from linnet.sim.rig import CameraSpec, project
from linnet.sim.rotations import quat_to_matrix
from linnet.sim.writer import read_lines_csv, read_points_csv


def _load_yaml(path: Path) -> dict:
    text = path.read_text(encoding="utf-8")
    if text.startswith("%YAML"):
        text = text.split("\n", 1)[1]
    return yaml.safe_load(text)


def read_camera_yaml(path) -> CameraSpec:
    """A EuRoC/Kalibr camera sensor.yaml (pinhole + radial-tangential) -> CameraSpec."""
    path = Path(path)
    d = _load_yaml(path)
    T = np.array(d["T_BS"]["data"], dtype=float).reshape(4, 4)
    w, h = d["resolution"]
    return CameraSpec(path.parent.name, int(w), int(h), [float(v) for v in d["intrinsics"]], "radtan",
                      [float(v) for v in d["distortion_coefficients"]], T, float(d.get("rate_hz", 20.0)))


def read_csv_ns(path) -> tuple[np.ndarray, np.ndarray]:
    """A EuRoC csv: int64 ns time stamps and the float columns after them."""
    t, rows = [], []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if not line or line.startswith("#"):
            continue
        f = line.split(",")
        t.append(int(f[0]))
        rows.append([float(x) for x in f[1:]])
    return np.array(t, dtype=np.int64), np.array(rows)


@dataclass
class SequenceTruth:
    root: Path
    cameras: list              # CameraSpec of cam0, cam1 (from the written sensor.yaml files)
    gt_t: np.ndarray           # (N,) ns
    gt: np.ndarray             # (N, 16): p, q_wxyz, v, b_w, b_a
    lines: np.ndarray          # (L, 2, 3) in W
    line_kinds: list
    points: np.ndarray         # (P, 3) in W
    point_kinds: list
    frames: np.ndarray         # (M,) camera time stamps, ns

    @classmethod
    def load(cls, root) -> "SequenceTruth":
        root = Path(root)
        mav0 = root / "mav0"
        cams = [read_camera_yaml(mav0 / c / "sensor.yaml") for c in ("cam0", "cam1")]
        gt_t, gt = read_csv_ns(mav0 / "state_groundtruth_estimate0" / "data.csv")
        lines, lk = read_lines_csv(root / "sim" / "lines.csv")
        pts, pk = read_points_csv(root / "sim" / "points.csv")
        frames = np.array([int(l.split(",")[0]) for l in (mav0 / "cam0" / "data.csv").read_text().splitlines()
                           if l and not l.startswith("#")], dtype=np.int64)
        return cls(root, cams, gt_t, gt, lines, lk, pts, pk, frames)

    def body_pose(self, t_ns: int) -> np.ndarray:
        """T_W_B at a time stamp of the ground truth (camera stamps are IMU stamps in simulated sequences)."""
        i = int(np.searchsorted(self.gt_t, t_ns))
        if i >= self.gt_t.size or self.gt_t[i] != t_ns:
            raise KeyError(f"{t_ns} is not a ground-truth time stamp")
        T = np.eye(4)
        T[:3, :3] = quat_to_matrix(self.gt[i, 3:7])
        T[:3, 3] = self.gt[i, 0:3]
        return T

    def camera_pose(self, t_ns: int, cam: int = 0) -> np.ndarray:
        return self.body_pose(t_ns) @ self.cameras[cam].T_B_C


def _visible(p_C: np.ndarray, px: np.ndarray, cam: CameraSpec, depth: Optional[np.ndarray], border: float,
             rel_tol: float) -> np.ndarray:
    ok = np.isfinite(px).all(axis=1) & (p_C[:, 2] > 0.1)
    ok &= (px[:, 0] >= border) & (px[:, 1] >= border) & (px[:, 0] <= cam.width - 1 - border) & \
          (px[:, 1] <= cam.height - 1 - border)
    if depth is not None:
        for i in np.nonzero(ok)[0]:
            c, r = int(round(px[i, 0])), int(round(px[i, 1]))
            win = depth[max(0, r - 1):r + 2, max(0, c - 1):c + 2]
            ok[i] = bool(np.any(np.abs(win - p_C[i, 2]) <= rel_tol * p_C[i, 2]))
    return ok


def project_points(points_W: np.ndarray, T_W_C: np.ndarray, cam: CameraSpec, depth: Optional[np.ndarray] = None,
                   border: float = 0.0, rel_tol: float = 0.02) -> tuple[np.ndarray, np.ndarray]:
    """Distorted pixel positions (P, 2) of W points and a visibility mask (in front, in the image, and - with the
    rendered depth map - not hidden: some pixel of the 3x3 neighbourhood has the point's depth within rel_tol)."""
    T_C_W = np.linalg.inv(T_W_C)
    p_C = points_W @ T_C_W[:3, :3].T + T_C_W[:3, 3]
    px = project(cam, p_C)
    return px, _visible(p_C, px, cam, depth, border, rel_tol)


def sample_segments(segments_W: np.ndarray, T_W_C: np.ndarray, cam: CameraSpec, depth: Optional[np.ndarray] = None,
                    step_m: float = 0.02, border: float = 5.0, rel_tol: float = 0.02):
    """Points every step_m along every segment, projected (with distortion, so images of lines are curves), with
    the image-plane unit normal of the projected curve at each point and visibility as in project_points.
    Returns (segment index (K,), pixels (K, 2), normals (K, 2), visible (K,))."""
    idx, pts, nrm, vis_parts = [], [], [], []
    T_C_W = np.linalg.inv(T_W_C)
    for i, (a, b) in enumerate(segments_W):
        n = max(2, int(np.linalg.norm(b - a) / step_m) + 1)
        s = np.linspace(0.0, 1.0, n)
        P = a + s[:, None] * (b - a)
        eps = 1e-4 * (b - a)
        p_C = P @ T_C_W[:3, :3].T + T_C_W[:3, 3]
        q_C = (P + eps) @ T_C_W[:3, :3].T + T_C_W[:3, 3]
        px, qx = project(cam, p_C), project(cam, q_C)
        d = qx - px
        norm = np.linalg.norm(d, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            tangent = d / norm
        idx.append(np.full(n, i))
        pts.append(px)
        nrm.append(np.stack([-tangent[:, 1], tangent[:, 0]], axis=1))
        vis_parts.append(_visible(p_C, px, cam, depth, border, rel_tol))
    if not idx:
        return np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, bool)
    return np.concatenate(idx), np.vstack(pts), np.vstack(nrm), np.concatenate(vis_parts) & \
        np.isfinite(np.vstack(nrm)).all(axis=1)
