"""Trajectories for the simulator: file loaders (TUM, EuRoC csv), the built-in analytic loop, and the C2
continuous-time fit (uniform cubic B-splines) from which poses, velocities, accelerations and angular rates are taken
analytically.

Continuous-time model: position p(t) is a uniform cubic B-spline in R^3; orientation is a uniform cubic B-spline on the
sign-unwrapped quaternion components, normalised: q(t) = s(t) / |s(t)|. Both are C2 in t, so the specific force and
the angular rate are continuous and exact derivatives of the poses written as ground truth:
    v_W = p'(t),  a_W = p''(t),  omega_B = 2 Im(conj(q) * q'(t)) = 2 Im(conj(q) * s'(t)) / |s(t)|.
(The normalised-quaternion spline is a simple alternative to the cumulative SO(3) B-spline of Kim et al., SIGGRAPH
1995 / Sommer et al., CVPR 2020: linear least squares instead of Gauss-Newton, same smoothness.) Knots are placed on
the IMU time grid (every `knot_dt` seconds from the first IMU sample), so that an integrator stepping on that grid never
straddles a knot.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from linnet import timeunits
from linnet.fileio import InputError, read_text_file
from linnet.sim.rotations import exp_so3, matrix_to_quat, quat_conj, quat_mul, quat_to_matrix

BUILTIN_PREFIX = "builtin:"
BUILTIN_NAMES = ("loop",)
GRAVITY_W = np.array([0.0, 0.0, -9.81])  # m/s^2, W has z up (DESIGN A3)


@dataclass
class TrajectorySamples:
    """Discrete poses of the body (IMU) frame in W. q is Hamilton, stored w, x, y, z."""
    t_ns: np.ndarray                   # (N,) int64
    p: np.ndarray                      # (N, 3) m
    q: np.ndarray                      # (N, 4) w x y z
    bias_gyr: Optional[np.ndarray] = None  # (N, 3) rad/s, when the file has them (17-column EuRoC csv)
    bias_acc: Optional[np.ndarray] = None  # (N, 3) m/s^2
    source: str = ""

    @property
    def duration(self) -> float:
        return float(self.t_ns[-1] - self.t_ns[0]) * 1e-9


# ----------------------------------------------------------------------------------------------------------- loading
def load_trajectory(spec: str) -> TrajectorySamples:
    """A path (TUM ``t x y z qx qy qz qw`` in seconds, or ms / us / ns judged by magnitude, or EuRoC csv ``t_ns, p, q_wxyz[, v, b_w, b_a]``) or the name
    of a built-in trajectory (``builtin:loop``)."""
    if spec.startswith(BUILTIN_PREFIX):
        name = spec[len(BUILTIN_PREFIX):]
        if name == "loop":
            return builtin_loop()
        raise InputError(f"unknown built-in trajectory '{spec}' (known: "
                         + ", ".join(BUILTIN_PREFIX + n for n in BUILTIN_NAMES) + ")")
    path = Path(spec)
    text = read_text_file(path, "a trajectory file", name_if_missing=True)
    rows, lines, tokens0, comma = [], [], [], None
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#") or line[0].isalpha():
            continue
        if comma is None:
            comma = "," in line
        fields = line.split(",") if comma else line.split()
        try:
            rows.append([float(x) for x in fields])
        except ValueError:
            raise InputError(f"{path}:{lineno}: cannot parse '{line[:60]}'") from None
        lines.append(lineno)
        tokens0.append(fields[0].strip())
        if len(rows[-1]) != len(rows[0]):
            raise InputError(f"{path}:{lineno}: {len(rows[-1])} columns, expected {len(rows[0])}")
        if not all(math.isfinite(x) for x in rows[-1]):
            raise InputError(f"{path}:{lineno}: non-finite value")
    if len(rows) < 4:
        raise InputError(f"{path}: need at least 4 poses, found {len(rows)}")
    ncol = len(rows[0])
    if comma:
        if ncol not in (8, 17):
            raise InputError(f"{path}:{lines[0]}: EuRoC csv needs 8 or 17 columns, found {ncol}")
        # Integer nanoseconds, every digit kept (a time with a decimal point is read by its magnitude).
        t_ns = _times_ns(path, lines, tokens0, integer_ns="." not in tokens0[0])
        data = np.array(rows)
        p, q = data[:, 1:4], data[:, 4:8]
        bg = data[:, 11:14] if ncol == 17 else None
        ba = data[:, 14:17] if ncol == 17 else None
    else:
        if ncol != 8:
            raise InputError(f"{path}:{lines[0]}: TUM needs 8 columns (t x y z qx qy qz qw), found {ncol}")
        data = np.array(rows)
        t_ns = _times_ns(path, lines, tokens0, integer_ns=False)
        if timeunits.unit_of(rows[0][0])[0] == "s":
            # Seconds with 5 decimals lose the sub-10-microsecond part; round to the nearest 10 us so 200 Hz stays
            # regular.
            t_ns = (np.round(t_ns / 1e4) * 1e4).astype(np.int64)
        p, q = data[:, 1:4], data[:, [7, 4, 5, 6]]
        bg = ba = None
    bad = np.nonzero(np.diff(t_ns) <= 0)[0]
    if bad.size:
        raise InputError(f"{path}:{lines[bad[0] + 1]}: time stamps not strictly increasing")
    norms = np.linalg.norm(q, axis=1)
    if np.any(np.abs(norms - 1.0) > 1e-2):
        i = int(np.argmax(np.abs(norms - 1.0)))
        raise InputError(f"{path}:{lines[i]}: quaternion norm {norms[i]:.4f} is not 1")
    return TrajectorySamples(t_ns, p.copy(), q / norms[:, None], bg, ba, source=str(path))


def _times_ns(path: Path, lines: list, tokens: list, integer_ns: bool) -> np.ndarray:
    """The time column in int64 ns, exactly (decimal arithmetic): integer ns for a EuRoC csv (`integer_ns`), otherwise
    in the unit given by the magnitude of the first time stamp (linnet.timeunits: s, ms, us or ns)."""
    scale = 1 if integer_ns else timeunits.unit_of(float(tokens[0]))[1]
    t = [timeunits.parse_time_ns(path, number, tok, scale) for number, tok in zip(lines, tokens)]
    return np.array(t, dtype=np.int64)


def _smootherstep_integral(x: np.ndarray) -> np.ndarray:
    """Integral from 0 to x of the C2 ramp 6x^5 - 15x^4 + 10x^3 (0 below 0, 1 above 1)."""
    xc = np.clip(x, 0.0, 1.0)
    inner = xc ** 6 - 3.0 * xc ** 5 + 2.5 * xc ** 4
    return np.where(x > 1.0, 0.5 + (x - 1.0), inner)


def builtin_loop(duration: float = 30.0, rate_hz: float = 200.0, t0_ns: int = 1_600_000_000_000_000_000
                 ) -> TrajectorySamples:
    """A figure-eight flight inside a room, like a hand-flown drone: 1 s at rest, a smooth 2.5 s speed-up, then
    0.55-1.25 m/s along a 5.6 m x 3.2 m figure-eight with height changes, yaw following the path plus a slow look-around,
    and banking roll / pitch of a few degrees. Body frame as on the EuRoC MAV: x up, z forward (the cameras look along
    body z)."""
    n = int(round(duration * rate_hz)) + 1
    t = np.arange(n) / rate_hz
    omega = 2.0 * math.pi / 22.0                   # rad/s of loop phase at cruise
    t_rest, t_ramp = 1.0, 2.5
    ramp = np.clip((t - t_rest) / t_ramp, 0.0, 1.0)
    ramp = ramp ** 3 * (10.0 - 15.0 * ramp + 6.0 * ramp ** 2)
    phi = omega * t_ramp * _smootherstep_integral((t - t_rest) / t_ramp)
    A, B = 2.8, 1.6                                # m, half extents of the figure-eight
    p = np.stack([A * np.sin(phi), B * np.sin(2.0 * phi), 1.3 + 0.35 * np.sin(1.5 * phi)], axis=1)
    # Heading along the path direction dp/dphi (defined even at rest) plus a slow look-around.
    psi = np.unwrap(np.arctan2(2.0 * B * np.cos(2.0 * phi), A * np.cos(phi))) + 0.45 * np.sin(0.7 * phi)
    roll = ramp * (0.14 * np.sin(2.0 * phi + 0.3))       # about body z (forward), ~8 deg
    pitch = ramp * (0.09 * np.sin(3.0 * phi + 1.0))      # about body y, ~5 deg
    c, s = np.cos(psi), np.sin(psi)
    x_b = np.tile([0.0, 0.0, 1.0], (n, 1))
    z_b = np.stack([c, s, np.zeros(n)], axis=1)
    y_b = np.cross(z_b, x_b)
    R_base = np.stack([x_b, y_b, z_b], axis=2)           # columns = body axes in W
    R = R_base @ exp_so3(np.stack([np.zeros(n), pitch, roll], axis=1))
    q = matrix_to_quat(R)
    t_ns = t0_ns + np.round(t * 1e9).astype(np.int64)
    return TrajectorySamples(t_ns, p, q, source="builtin:loop")


# ------------------------------------------------------------------------------------------------------ the spline
def _basis(u: np.ndarray, order: int) -> np.ndarray:
    """Uniform cubic B-spline basis (or its first / second derivative w.r.t. u) at u in [0, 1]: (N, 4)."""
    if order == 0:
        return np.stack([(1 - u) ** 3, 3 * u ** 3 - 6 * u ** 2 + 4, -3 * u ** 3 + 3 * u ** 2 + 3 * u + 1, u ** 3],
                        axis=1) / 6.0
    if order == 1:
        return np.stack([-(1 - u) ** 2, 3 * u ** 2 - 4 * u, -3 * u ** 2 + 2 * u + 1, u ** 2], axis=1) / 2.0
    return np.stack([1 - u, 3 * u - 2, 1 - 3 * u, u], axis=1)


@dataclass
class SplineState:
    """Everything the simulator needs at a set of times (all in W unless noted)."""
    p: np.ndarray        # (N, 3) position of B, m
    q: np.ndarray        # (N, 4) q_W_B, w x y z
    R: np.ndarray        # (N, 3, 3) R_W_B
    v: np.ndarray        # (N, 3) velocity, m/s
    a: np.ndarray        # (N, 3) acceleration, m/s^2
    omega_B: np.ndarray  # (N, 3) angular rate in B, rad/s
    f_B: np.ndarray      # (N, 3) specific force in B = R^T (a - g), m/s^2


class SplineTrajectory:
    """Uniform cubic B-splines on position and on quaternion components, knots every dt seconds from t0_ns."""

    def __init__(self, t0_ns: int, dt: float, ctrl_p: np.ndarray, ctrl_q: np.ndarray):
        self.t0_ns, self.dt = int(t0_ns), float(dt)
        self.ctrl_p, self.ctrl_q = np.asarray(ctrl_p, float), np.asarray(ctrl_q, float)
        self.n_segments = self.ctrl_p.shape[0] - 3

    @property
    def t_end_ns(self) -> int:
        return self.t0_ns + int(round(self.n_segments * self.dt * 1e9))

    def _locate(self, t_ns: np.ndarray):
        tau = (np.asarray(t_ns, dtype=np.int64) - self.t0_ns).astype(float) * 1e-9 / self.dt
        seg = np.clip(np.floor(tau).astype(np.int64), 0, self.n_segments - 1)
        return seg, tau - seg

    def evaluate(self, t_ns) -> SplineState:
        t_ns = np.atleast_1d(np.asarray(t_ns, dtype=np.int64))
        seg, u = self._locate(t_ns)
        idx = seg[:, None] + np.arange(4)[None, :]
        b0, b1, b2 = _basis(u, 0), _basis(u, 1) / self.dt, _basis(u, 2) / self.dt ** 2
        cp, cq = self.ctrl_p[idx], self.ctrl_q[idx]          # (N, 4, 3), (N, 4, 4)
        p = np.einsum("nk,nkd->nd", b0, cp)
        v = np.einsum("nk,nkd->nd", b1, cp)
        a = np.einsum("nk,nkd->nd", b2, cp)
        s = np.einsum("nk,nkd->nd", b0, cq)
        ds = np.einsum("nk,nkd->nd", b1, cq)
        norm = np.linalg.norm(s, axis=1, keepdims=True)
        q = s / norm
        omega = 2.0 * quat_mul(quat_conj(q), ds / norm)[:, 1:]
        R = quat_to_matrix(q)
        f_B = np.einsum("nji,nj->ni", R, a - GRAVITY_W)
        return SplineState(p, q, R, v, a, omega, f_B)

    @classmethod
    def fit(cls, samples: TrajectorySamples, t_start_ns: int, t_end_ns: int, dt: float = 0.1,
            smoothing: float = 1e-6) -> tuple["SplineTrajectory", dict]:
        """Least-squares fit to the samples within [t_start, t_end] (with a tiny second-difference regulariser that
        only matters where samples are missing). Returns the spline and the fit residual (RMS / max position error in
        m, RMS / max rotation error in degrees)."""
        n_seg = max(1, int(math.ceil((t_end_ns - t_start_ns) * 1e-9 / dt - 1e-9)))
        spline = cls(t_start_ns, dt, np.zeros((n_seg + 3, 3)), np.zeros((n_seg + 3, 4)))
        # Samples inside the spline's domain [t_start, t_start + n_seg dt] (which reaches up to dt past t_end).
        sel = (samples.t_ns >= t_start_ns) & (samples.t_ns <= spline.t_end_ns)
        t, P, Q = samples.t_ns[sel], samples.p[sel], samples.q[sel].copy()
        if t.size < 4:
            raise InputError(f"{samples.source}: fewer than 4 poses inside the requested time range")
        # Quaternion sign continuity, so that the component spline does not pass through zero.
        for i in range(1, Q.shape[0]):
            if np.dot(Q[i], Q[i - 1]) < 0.0:
                Q[i] = -Q[i]
        seg, u = spline._locate(t)
        B = _basis(np.clip(u, 0.0, 1.0), 0)
        m = n_seg + 3
        AtA = np.zeros((m, m))
        rows = seg[:, None] + np.arange(4)[None, :]
        for j in range(4):
            for k in range(4):
                np.add.at(AtA, (rows[:, j], rows[:, k]), B[:, j] * B[:, k])
        Aty = np.zeros((m, 7))
        Y = np.hstack([P, Q])
        for j in range(4):
            np.add.at(Aty, rows[:, j], B[:, j:j + 1] * Y)
        D = np.zeros((m - 2, m))
        ar = np.arange(m - 2)
        D[ar, ar], D[ar, ar + 1], D[ar, ar + 2] = 1.0, -2.0, 1.0
        lam = smoothing * max(1.0, t.size / n_seg)
        # The normal matrix is symmetric positive definite and banded (3 off-diagonals): a banded Cholesky solve
        # (LAPACK pbsv) is exact, cheap, and unlike a dense solve gives the same bits whatever BLAS's thread count
        # (a Ray worker runs with OMP_NUM_THREADS=1: replays must not depend on where they were rendered).
        from scipy.linalg import solveh_banded  # here, not at module level: scipy.linalg costs ~0.13 s to import

        N = AtA + lam * (D.T @ D) + 1e-12 * np.eye(m)
        bands = np.zeros((4, m))
        for k in range(4):
            bands[3 - k, k:] = np.diagonal(N, offset=k)
        X = solveh_banded(bands, Aty, lower=False, check_finite=False)
        spline.ctrl_p, spline.ctrl_q = X[:, :3], X[:, 3:]
        inside = (t >= t_start_ns) & (t <= t_end_ns)
        st = spline.evaluate(t[inside])
        dp = np.linalg.norm(st.p - P[inside], axis=1)
        dq = quat_mul(quat_conj(st.q), Q[inside])
        ang = np.degrees(2.0 * np.arctan2(np.linalg.norm(dq[:, 1:], axis=1), np.abs(dq[:, 0])))
        residual = {"position_rms_m": float(np.sqrt(np.mean(dp ** 2))), "position_max_m": float(dp.max()),
                    "rotation_rms_deg": float(np.sqrt(np.mean(ang ** 2))), "rotation_max_deg": float(ang.max()),
                    "samples": int(inside.sum()), "knot_dt_s": dt}
        return spline, residual
