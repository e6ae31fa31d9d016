"""Line front-end helpers: run the C++ LineTracker over a EuRoC folder, draw tracked lines, score against ground truth.

    from linnet import lines
    data = lines.EurocStereo("path/to/V1_01_easy")          # the folder holding mav0/
    tracker = lines.make_tracker(data)                     # linnet._linnet.LineTracker
    for t_ns, left, right in data.frames():
        obs = tracker.track(t_ns, left, right)             # dict of numpy arrays, see LineTracker.track
        timings = tracker.last_timings()

The scoring functions (`match_segment`, `detection_recall`, `pair_precision`) are pure numpy and need no compiled core.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Optional, Sequence

import numpy as np


class DatasetError(ValueError):
    """A EuRoC folder that cannot be read; the message names the file."""


# ----------------------------------------------------------------------------------------------------------------
# EuRoC reading (cam0 / cam1 data.csv + PNGs, sensor.yaml)


def _read_sensor_yaml(path: Path) -> dict:
    import yaml

    try:
        text = path.read_text(encoding="utf-8")
    except OSError as e:
        raise DatasetError(f"{path}: cannot read ({e.strerror})") from e
    # EuRoC files start with OpenCV's "%YAML:1.0" directive, which PyYAML does not accept.
    lines = [ln for ln in text.splitlines() if not ln.startswith("%YAML")]
    try:
        doc = yaml.safe_load("\n".join(lines))
    except yaml.YAMLError as e:
        raise DatasetError(f"{path}: not valid YAML ({e})") from e
    try:
        T = np.array(doc["T_BS"]["data"], dtype=float).reshape(4, 4)
        width, height = (int(v) for v in doc["resolution"])
        intrinsics = [float(v) for v in doc["intrinsics"]]
        model = str(doc.get("distortion_model", "radial-tangential"))
        coeffs = [float(v) for v in doc.get("distortion_coefficients", [])]
    except (KeyError, TypeError, ValueError) as e:
        raise DatasetError(f"{path}: missing or malformed key ({e})") from e
    distortion = {"radial-tangential": "radtan", "radtan": "radtan", "equidistant": "equidistant",
                  "fisheye": "equidistant", "none": "none"}.get(model)
    if distortion is None:
        raise DatasetError(f"{path}: unsupported distortion_model '{model}'")
    return {"width": width, "height": height, "intrinsics": intrinsics, "distortion": distortion,
            "distortion_coeffs": coeffs, "T_B_C": T}


def _read_image_list(csv_path: Path) -> list[tuple[int, Path]]:
    if not csv_path.is_file():
        raise DatasetError(f"{csv_path}: missing")
    out = []
    with open(csv_path, newline="", encoding="utf-8") as f:
        for lineno, row in enumerate(csv.reader(f), start=1):
            if not row or row[0].startswith("#"):
                continue
            try:
                out.append((int(row[0]), csv_path.parent / "data" / row[1].strip()))
            except (ValueError, IndexError) as e:
                raise DatasetError(f"{csv_path}:{lineno}: expected 'timestamp_ns,filename'") from e
    return out


@dataclass
class EurocStereo:
    """A EuRoC ASL folder (the one holding mav0/): calibration and time-matched stereo frames."""

    root: Path

    def __post_init__(self):
        self.root = Path(self.root)
        mav0 = self.root / "mav0" if (self.root / "mav0").is_dir() else self.root
        self.cam0 = _read_sensor_yaml(mav0 / "cam0" / "sensor.yaml")
        self.stereo = (mav0 / "cam1" / "data.csv").is_file()
        self.cam1 = _read_sensor_yaml(mav0 / "cam1" / "sensor.yaml") if self.stereo else None
        left = _read_image_list(mav0 / "cam0" / "data.csv")
        right = dict(_read_image_list(mav0 / "cam1" / "data.csv")) if self.stereo else {}
        self.images = [(t, p, right.get(t)) for t, p in left if not self.stereo or t in right]
        if not self.images:
            raise DatasetError(f"{mav0 / 'cam0' / 'data.csv'}: no (stereo) images")

    @property
    def T_C1_C0(self) -> Optional[np.ndarray]:
        if not self.stereo:
            return None
        return np.linalg.inv(self.cam1["T_B_C"]) @ self.cam0["T_B_C"]

    def __len__(self) -> int:
        return len(self.images)

    def frames(self, start: int = 0, stop: Optional[int] = None) -> Iterator[tuple[int, np.ndarray, Optional[np.ndarray]]]:
        """Yields (t_ns, left, right) uint8 images for frames [start, stop)."""
        import cv2

        for t, lp, rp in self.images[start:stop]:
            left = cv2.imread(str(lp), cv2.IMREAD_GRAYSCALE)
            if left is None:
                raise DatasetError(f"{lp}: cannot read image")
            right = None
            if rp is not None:
                right = cv2.imread(str(rp), cv2.IMREAD_GRAYSCALE)
                if right is None:
                    raise DatasetError(f"{rp}: cannot read image")
            yield t, left, right


def camera_dict(cam: dict) -> dict:
    """The plain calibration values LineTracker takes."""
    return {k: cam[k] for k in ("width", "height", "intrinsics", "distortion", "distortion_coeffs")}


def make_tracker(data: EurocStereo, options: Optional[dict] = None, mono: bool = False):
    """A compiled LineTracker for the dataset's rig (options: {"key.path": value} overrides)."""
    from linnet import _linnet

    if mono or not data.stereo:
        return _linnet.LineTracker(camera_dict(data.cam0), None, None, dict(options or {}))
    return _linnet.LineTracker(camera_dict(data.cam0), camera_dict(data.cam1), data.T_C1_C0, dict(options or {}))


def parse_frames(spec: Optional[str], count: int) -> tuple[int, int]:
    """'A:B' (either side optional, negative from the end) -> [start, stop) clipped to [0, count]."""
    if spec is None or spec == "":
        return 0, count
    if ":" not in spec:
        raise ValueError(f"--frames expects A:B, got '{spec}'")
    a, b = spec.split(":", 1)
    try:
        s = slice(int(a) if a.strip() else None, int(b) if b.strip() else None)
    except ValueError as e:
        raise ValueError(f"--frames expects integers A:B, got '{spec}'") from e
    start, stop, _ = s.indices(count)
    if stop <= start:
        raise ValueError(f"--frames {spec} selects no frame of {count}")
    return start, stop


# ----------------------------------------------------------------------------------------------------------------
# Drawing


def id_colour(i: int) -> tuple[int, int, int]:
    """A stable, well-spread BGR colour per id (golden-ratio hue walk)."""
    import colorsys

    h = (int(i) * 0.618033988749895) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.85, 1.0)
    return int(b * 255), int(g * 255), int(r * 255)


def draw_tracks(left: np.ndarray, right: Optional[np.ndarray], obs: dict, label: str = "") -> np.ndarray:
    """Left | right side by side (BGR), each line coloured by id; right lines only where matched."""
    import cv2

    L = cv2.cvtColor(left, cv2.COLOR_GRAY2BGR)
    R = cv2.cvtColor(right, cv2.COLOR_GRAY2BGR) if right is not None else np.zeros_like(L)
    for k in range(len(obs["id"])):
        c = id_colour(int(obs["id"][k]))
        a, b = obs["ps0"][k], obs["pe0"][k]
        cv2.line(L, (int(round(a[0])), int(round(a[1]))), (int(round(b[0])), int(round(b[1]))), c, 2, cv2.LINE_AA)
        cv2.circle(L, (int(round(a[0])), int(round(a[1]))), 2, c, -1)
        if obs["has_right"][k]:
            a, b = obs["ps1"][k], obs["pe1"][k]
            cv2.line(R, (int(round(a[0])), int(round(a[1]))), (int(round(b[0])), int(round(b[1]))), c, 2, cv2.LINE_AA)
            cv2.circle(R, (int(round(a[0])), int(round(a[1]))), 2, c, -1)
    out = np.hstack([L, R])
    if label:
        cv2.putText(out, label, (8, 20), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (255, 255, 255), 1, cv2.LINE_AA)
    return out


# ----------------------------------------------------------------------------------------------------------------
# Ground-truth scoring (issue 4): a detection matches a ground-truth segment when both its endpoints lie within
# `tol_px` of the segment's projected (possibly curved, by distortion) image and they overlap >= `min_overlap`.


def _polyline_param(poly: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """Distance from point p to the polyline and the arc length of its foot point."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    L2 = np.maximum((ab * ab).sum(1), 1e-18)
    t = np.clip(((p - a) * ab).sum(1) / L2, 0.0, 1.0)
    foot = a + t[:, None] * ab
    d = np.linalg.norm(foot - p, axis=1)
    k = int(np.argmin(d))
    seglen = np.sqrt(L2)
    arc = float(seglen[:k].sum() + t[k] * seglen[k])
    return float(d[k]), arc


def match_segment(det: np.ndarray, gt_poly: np.ndarray, tol_px: float = 2.0, min_overlap: float = 0.5,
                  overlap_of: str = "gt") -> bool:
    """det: (4,) x0 y0 x1 y1 in pixels. gt_poly: (M, 2) samples of the projected ground-truth segment in order.
    overlap_of: "gt" (intersection / ground-truth length: a detection covers half the segment, used for recall)
    or "shorter" (intersection / shorter of the two, used to identify which segment a detection belongs to)."""
    gt_poly = np.asarray(gt_poly, dtype=float)
    det = np.asarray(det, dtype=float).reshape(4)
    if len(gt_poly) < 2:
        return False
    d0, a0 = _polyline_param(gt_poly, det[:2])
    d1, a1 = _polyline_param(gt_poly, det[2:])
    if max(d0, d1) > tol_px:
        return False
    total = float(np.linalg.norm(np.diff(gt_poly, axis=0), axis=1).sum())
    inter = abs(a1 - a0)  # the foot points lie on the polyline, so their span is inside it
    det_len = float(np.hypot(det[2] - det[0], det[3] - det[1]))
    denom = total if overlap_of == "gt" else max(1e-9, min(total, det_len))
    return inter >= min_overlap * denom


def detection_recall(dets: np.ndarray, gt_polys: Sequence[np.ndarray], min_length_px: float = 40.0,
                     tol_px: float = 2.0, min_overlap: float = 0.5) -> tuple[int, int]:
    """(matched, considered) ground-truth segments: those longer than min_length_px, matched by any detection."""
    dets = np.asarray(dets, dtype=float).reshape(-1, 4)
    considered = matched = 0
    for poly in gt_polys:
        poly = np.asarray(poly, dtype=float)
        if len(poly) < 2 or np.linalg.norm(np.diff(poly, axis=0), axis=1).sum() < min_length_px:
            continue
        considered += 1
        if any(match_segment(d, poly, tol_px, min_overlap, "gt") for d in dets):
            matched += 1
    return matched, considered


def assign_segment(det: np.ndarray, gt_polys: Sequence[np.ndarray], tol_px: float = 2.0,
                   min_overlap: float = 0.5) -> int:
    """Index of the ground-truth segment a detection lies on (closest), or -1."""
    best, best_d = -1, np.inf
    det = np.asarray(det, dtype=float).reshape(4)
    for i, poly in enumerate(gt_polys):
        poly = np.asarray(poly, dtype=float)
        if len(poly) < 2 or not match_segment(det, poly, tol_px, min_overlap, "shorter"):
            continue
        d = max(_polyline_param(poly, det[:2])[0], _polyline_param(poly, det[2:])[0])
        if d < best_d:
            best, best_d = i, d
    return best


def pair_precision(labels_a: Sequence[int], labels_b: Sequence[int]) -> tuple[int, int]:
    """(correct, judged) over matched pairs whose both sides lie on a known segment (label >= 0)."""
    judged = correct = 0
    for a, b in zip(labels_a, labels_b):
        if a < 0 or b < 0:
            continue
        judged += 1
        correct += int(a == b)
    return correct, judged


def percentile_table(values: dict[str, Sequence[float]]) -> dict[str, dict[str, float]]:
    """{name: {median, p95, max}} of each series."""
    out = {}
    for name, v in values.items():
        a = np.asarray(v, dtype=float)
        if a.size == 0:
            out[name] = {"median": float("nan"), "p95": float("nan"), "max": float("nan")}
        else:
            out[name] = {"median": float(np.median(a)), "p95": float(np.percentile(a, 95)), "max": float(a.max())}
    return out
