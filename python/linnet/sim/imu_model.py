"""A measured IMU noise model: the power spectral density of a real IMU's error, per axis and flight phase.

The error of a real IMU against its ground truth (``residuals``) is

    e(t) = measurement(t) - ideal(t) - bias(t),

ideal(t) being the angular rate / specific force of the ground-truth motion (the simulator's own cubic B-spline fit of
the ground-truth poses, so that a replay's residual is made the same way) and bias(t) the ground truth's biases. On a
multicopter e(t) is much more than the datasheet's white noise: the rotors shake the airframe, which puts narrow peaks
and broad humps into the spectrum, and they only do so once the rotors spin up. The model therefore holds one
one-sided PSD per axis for each of two phases, ``rest`` (on the ground, not moving) and ``flight``, estimated with
Welch's method (Welch, IEEE Trans. Audio Electroacoust. 15(2), 1967) on the runs of samples of each phase.

Synthesis (``synthesize_noise``) shapes white Gaussian noise in the frequency domain to each phase's spectrum and
cross-fades the two with the replayed motion's phase (1 s ramps, variances blended linearly). The bias random walks
are added by the caller (``linnet.sim.imu.synthesize``) as before, with the model's random-walk densities.

Units: PSD in (rad/s)^2/Hz (gyroscope, axes 0-2) and (m/s^2)^2/Hz (accelerometer, axes 3-5); frequencies in Hz.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import yaml

from linnet.sim.trajectory import InputError, SplineState

AXES = ("gyr_x", "gyr_y", "gyr_z", "acc_x", "acc_y", "acc_z")
PHASES = ("rest", "flight")
MODEL_KIND = "linnet-measured-imu-noise"


@dataclass
class PhaseRule:
    """When the MAV counts as flying: moving faster than speed_mps, or higher than height_m above where it started.
    A phase run shorter than min_run_s is merged into its neighbours (hovering pauses stay in flight)."""
    speed_mps: float = 0.05     # m/s
    height_m: float = 0.05      # m above the first sample's height
    min_run_s: float = 2.0      # s
    ramp_s: float = 1.0         # s, cross-fade between the phases' spectra in synthesis


@dataclass
class MeasuredImuModel:
    rate_hz: float                      # sample rate the spectra were estimated at (Hz)
    freqs_hz: np.ndarray                # (K,) frequencies of the PSD bins, 0 .. rate_hz / 2
    psd: dict                           # phase -> (6, K) one-sided PSD, axes AXES
    std: dict                           # phase -> (6,) standard deviation of the modelled error (PSD integral)
    seconds: dict                       # phase -> seconds of data the spectrum was estimated from
    rule: PhaseRule = field(default_factory=PhaseRule)
    # Bias random walks and initial bias spreads (the datasheet values: the ground truth's biases are too smooth an
    # estimate to fit a random walk to).
    gyroscope_random_walk: float = 1.9393e-05       # rad/s^2/sqrt(Hz)
    accelerometer_random_walk: float = 3.0000e-3    # m/s^3/sqrt(Hz)
    initial_gyro_bias_sigma: float = 0.01           # rad/s
    initial_accel_bias_sigma: float = 0.05          # m/s^2
    source: str = ""

    # ---------------------------------------------------------------------------------------------------------- io
    def to_dict(self) -> dict:
        return {
            "kind": MODEL_KIND, "source": self.source, "rate_hz": float(self.rate_hz),
            "phase_rule": {"speed_mps": self.rule.speed_mps, "height_m": self.rule.height_m,
                           "min_run_s": self.rule.min_run_s, "ramp_s": self.rule.ramp_s},
            "gyroscope_random_walk": self.gyroscope_random_walk,
            "accelerometer_random_walk": self.accelerometer_random_walk,
            "initial_gyro_bias_sigma": self.initial_gyro_bias_sigma,
            "initial_accel_bias_sigma": self.initial_accel_bias_sigma,
            "freqs_hz": [round(float(f), 6) for f in self.freqs_hz],
            "phases": {ph: {"seconds": round(float(self.seconds[ph]), 3),
                            "std": {ax: float(f"{v:.5g}") for ax, v in zip(AXES, self.std[ph])},
                            "psd": {ax: [float(f"{v:.5g}") for v in self.psd[ph][i]] for i, ax in enumerate(AXES)}}
                       for ph in PHASES},
        }

    def save(self, path) -> None:
        header = ("# Linnet measured IMU noise model (linnet sim fit-imu). PSD: one-sided, (rad/s)^2/Hz for gyr_*,\n"
                  "# (m/s^2)^2/Hz for acc_*, at freqs_hz; std: the PSD's integral, square-rooted.\n")
        Path(path).write_text(header + yaml.safe_dump(self.to_dict(), sort_keys=False, width=120, default_flow_style=None), encoding="utf-8")

    @classmethod
    def from_dict(cls, d: dict, where: str) -> "MeasuredImuModel":
        def need(mapping, key, ctx):
            if not isinstance(mapping, dict) or key not in mapping:
                raise InputError(f"{where}: missing key '{ctx}{key}'")
            return mapping[key]

        if d.get("kind") != MODEL_KIND:
            raise InputError(f"{where}: not a measured IMU model (kind must be '{MODEL_KIND}')")
        freqs = np.asarray(need(d, "freqs_hz", ""), dtype=float)
        rate = float(need(d, "rate_hz", ""))
        if freqs.ndim != 1 or freqs.size < 4 or np.any(np.diff(freqs) <= 0) or not (0 < rate <= 1e5):
            raise InputError(f"{where}: freqs_hz must be increasing (>= 4 values) and rate_hz positive")
        phases = need(d, "phases", "")
        psd, std, seconds = {}, {}, {}
        for ph in PHASES:
            p = need(phases, ph, "phases.")
            rows = [np.asarray(need(need(p, "psd", f"phases.{ph}."), ax, f"phases.{ph}.psd."), float) for ax in AXES]
            if any(r.shape != freqs.shape or np.any(~np.isfinite(r)) or np.any(r < 0) for r in rows):
                raise InputError(f"{where}: phases.{ph}.psd: each axis needs {freqs.size} non-negative numbers")
            psd[ph] = np.vstack(rows)
            std[ph] = np.array([float(need(p, "std", f"phases.{ph}.").get(ax, math.nan)) for ax in AXES])
            seconds[ph] = float(p.get("seconds", 0.0))
        r = d.get("phase_rule", {}) or {}
        rule = PhaseRule(**{k: float(v) for k, v in r.items() if k in PhaseRule.__dataclass_fields__})
        model = cls(rate, freqs, psd, std, seconds, rule, source=str(d.get("source", "")))
        for key in ("gyroscope_random_walk", "accelerometer_random_walk", "initial_gyro_bias_sigma",
                    "initial_accel_bias_sigma"):
            if key in d:
                value = d[key]
                if not isinstance(value, (int, float)) or value < 0:
                    raise InputError(f"{where}: key '{key}' must be a non-negative number, got {value!r}")
                setattr(model, key, float(value))
        return model

    @classmethod
    def load(cls, path) -> "MeasuredImuModel":
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError) as e:
            raise InputError(f"{path}: cannot read the IMU model: {e}") from None
        except yaml.YAMLError as e:
            raise InputError(f"{path}: not valid YAML: {e}") from None
        return cls.from_dict(data or {}, str(path))


def shipped_model_path() -> Path:
    """The model fitted to EuRoC V1_01_easy (ADIS16448 on the AscTec Firefly), shipped with Linnet."""
    return Path(__file__).with_name("data") / "imu_measured_v1_01.yaml"


# ------------------------------------------------------------------------------------------------------ phases


def flight_mask(t_ns: np.ndarray, state: SplineState, rule: PhaseRule) -> np.ndarray:
    """(N,) bool, True where the motion counts as flight (see PhaseRule). Short runs are merged into neighbours."""
    speed = np.linalg.norm(state.v, axis=1)
    height = state.p[:, 2] - state.p[0, 2]
    flying = (speed > rule.speed_mps) | (height > rule.height_m)
    if flying.size < 2:
        return flying
    dt = float(np.median(np.diff(t_ns))) * 1e-9
    min_run = max(1, int(round(rule.min_run_s / max(dt, 1e-9))))
    # Merge short runs, shortest first (the earliest of equals), until every run is long enough or one is left.
    while True:
        runs = _runs(flying)
        start, end, value = min(runs, key=lambda r: r[1] - r[0])
        if len(runs) <= 1 or end - start >= min_run:
            return flying
        flying[start:end] = not value


def _runs(mask: np.ndarray):
    starts = np.flatnonzero(np.r_[True, mask[1:] != mask[:-1]])
    ends = np.r_[starts[1:], mask.size]
    return [(int(s), int(e), bool(mask[s])) for s, e in zip(starts, ends)]


# ------------------------------------------------------------------------------------------------------ fitting


def welch_psd(x: np.ndarray, runs, rate_hz: float, nperseg: int):
    """One-sided PSD (6, K) of the rows of x (N, 6) over the given [start, end) runs: Welch's average of Hann-windowed,
    mean-removed periodograms. In each run the segments are spread evenly from its first to its last sample (at least
    50 % overlap), so that the whole run counts, its end as much as its start. Returns (freqs, psd, seconds used)."""
    window = np.hanning(nperseg + 2)[1:-1]  # symmetric Hann without its zero end points
    scale = 2.0 / (rate_hz * np.sum(window ** 2))  # one-sided density
    total = np.zeros((x.shape[1], nperseg // 2 + 1))
    count, used = 0, 0
    for s, e in runs:
        n = e - s
        if n < nperseg:
            continue
        segments = 1 + int(math.ceil((n - nperseg) / (nperseg / 2)))
        for start in np.round(np.linspace(s, e - nperseg, segments)).astype(int):
            seg = x[start:start + nperseg]
            spectrum = np.fft.rfft((seg - seg.mean(axis=0)) * window[:, None], axis=0)
            p = scale * np.abs(spectrum) ** 2
            p[0] *= 0.5
            if nperseg % 2 == 0:
                p[-1] *= 0.5
            total += p.T
            count += 1
        used += n
    if count == 0:
        return None, None, 0.0
    return np.fft.rfftfreq(nperseg, d=1.0 / rate_hz), total / count, used / rate_hz


def band_std(freqs_hz: np.ndarray, psd: np.ndarray, low_hz: float, high_hz: float) -> np.ndarray:
    """Standard deviation in [low_hz, high_hz] of each row of psd: the square root of the PSD's integral there."""
    sel = (freqs_hz >= low_hz) & (freqs_hz <= high_hz)
    df = float(freqs_hz[1] - freqs_hz[0])
    return np.sqrt(psd[:, sel].sum(axis=1) * df)


def fit_model(t_ns: np.ndarray, error: np.ndarray, state: SplineState, rule: Optional[PhaseRule] = None,
              nperseg: tuple = (256, 1024), trim_s: float = 1.0, flat_below_hz: float = 1.0,
              source: str = "") -> MeasuredImuModel:
    """Fit the two phases' spectra to an IMU error series (N, 6) at regular times t_ns, with the ground-truth motion
    `state` at the same times. trim_s seconds at either end are left out (the spline fit is weakest there). Below
    flat_below_hz the error is mostly the ground truth's own (poses at 20 Hz through a spline with 0.1 s knots), not
    the IMU's: the spectrum there is continued flat at its lowest value in [flat_below_hz, 2 flat_below_hz].
    nperseg: Welch segment lengths (samples) of the rest and flight phases: the rest phase is short (seconds), the
    flight long enough for a finer resolution, which keeps the vibration peaks narrow. The spectra are stored on the
    finer grid (the coarser one interpolated linearly)."""
    rule = rule or PhaseRule()
    if t_ns.size < 2:
        raise InputError("fit-imu: fewer than 2 IMU samples overlap the ground truth")
    rate = 1e9 / float(np.median(np.diff(t_ns)))
    mask = flight_mask(t_ns, state, rule)
    trim = int(round(trim_s * rate))
    psd, std, seconds, grids = {}, {}, {}, {}
    for ph, flying, segment in zip(PHASES, (False, True), nperseg):
        runs = [(max(s, trim), min(e, t_ns.size - trim)) for s, e, fl in _runs(mask) if fl == flying]
        runs = [(s, e) for s, e in runs if e > s]
        f, p, sec = welch_psd(error, runs, rate, segment)
        if p is None:
            raise InputError(f"fit-imu: no {ph} run of at least {segment / rate:.2f} s in the data "
                             f"(phase rule: speed > {rule.speed_mps} m/s or height > {rule.height_m} m is flight)")
        low = f < flat_below_hz
        if low.any():
            p[:, low] = p[:, (f >= flat_below_hz) & (f <= 2.0 * flat_below_hz)].min(axis=1, keepdims=True)
        psd[ph], grids[ph], seconds[ph] = p, f, sec
    freqs = max(grids.values(), key=len)
    for ph in PHASES:
        psd[ph] = np.vstack([np.interp(freqs, grids[ph], row) for row in psd[ph]])
        std[ph] = band_std(freqs, psd[ph], 0.0, rate / 2.0)
    return MeasuredImuModel(rate, freqs, psd, std, seconds, rule, source=source)


def imu_error(imu_t: np.ndarray, gyr: np.ndarray, acc: np.ndarray, gt, knot_dt: float = 0.1, where: str = ""):
    """The error of IMU samples against a ground truth with biases (a TrajectorySamples from a 17-column EuRoC csv):
    returns (t_ns, error (N, 6), state) for the samples inside the ground truth's time range, state being the spline
    fit's motion at t_ns (the same fit as the simulator's, knots every knot_dt seconds)."""
    from linnet.sim.imu import interpolate_biases
    from linnet.sim.trajectory import SplineTrajectory

    if gt.bias_gyr is None or gt.bias_acc is None:
        raise InputError(f"{where or gt.source}: the ground truth has no bias columns (a 17-column EuRoC "
                         "state_groundtruth_estimate0/data.csv is needed to separate the biases from the noise)")
    keep = (imu_t >= gt.t_ns[0]) & (imu_t <= gt.t_ns[-1])
    if keep.sum() < 4:
        raise InputError(f"{where or gt.source}: fewer than 4 IMU samples inside the ground truth's time range "
                         f"[{gt.t_ns[0]}, {gt.t_ns[-1]}] ns")
    t = imu_t[keep]
    spline, _fit = SplineTrajectory.fit(gt, int(t[0]), int(t[-1]), dt=knot_dt)
    state = spline.evaluate(t)
    error = np.hstack([gyr[keep] - state.omega_B - interpolate_biases(t, gt.t_ns, gt.bias_gyr),
                       acc[keep] - state.f_B - interpolate_biases(t, gt.t_ns, gt.bias_acc)])
    return t, error, state


# ---------------------------------------------------------------------------------------------------- synthesis


def shaped_noise(psd_row: np.ndarray, freqs_hz: np.ndarray, n: int, rate_hz: float,
                 white: np.ndarray) -> np.ndarray:
    """n samples at rate_hz of Gaussian noise with the one-sided PSD psd_row(freqs_hz), made by shaping `white`
    (n standard normal samples) in the frequency domain: |H(f)|^2 = S(f) rate / 2 keeps the variance = integral of S."""
    spectrum = np.fft.rfft(white)
    f = np.fft.rfftfreq(n, d=1.0 / rate_hz)
    gain = np.sqrt(np.interp(f, freqs_hz, psd_row) * rate_hz / 2.0)
    return np.fft.irfft(spectrum * gain, n=n)


def synthesize_noise(model: MeasuredImuModel, t_ns: np.ndarray, state: SplineState,
                     rng: np.random.Generator) -> np.ndarray:
    """(N, 6) IMU error samples (gyr xyz, acc xyz) at t_ns for the motion `state`: each phase's spectrum, cross-faded
    with the motion's phase. Draws 2 x 6 x N standard normal numbers from rng (rest first, then flight)."""
    n = t_ns.size
    rate = 1e9 / float(np.median(np.diff(t_ns))) if n > 1 else model.rate_hz
    white = rng.standard_normal((2, 6, n))
    flying = flight_mask(t_ns, state, model.rule).astype(float)
    ramp = max(1, int(round(model.rule.ramp_s * rate)))
    if ramp > 1 and n > 1:
        kernel = np.ones(ramp) / ramp
        w = np.convolve(np.pad(flying, (ramp // 2, ramp - 1 - ramp // 2), mode="edge"), kernel, mode="valid")
    else:
        w = flying
    out = np.empty((n, 6))
    for axis in range(6):
        rest = shaped_noise(model.psd["rest"][axis], model.freqs_hz, n, rate, white[0, axis])
        flight = shaped_noise(model.psd["flight"][axis], model.freqs_hz, n, rate, white[1, axis])
        out[:, axis] = np.sqrt(1.0 - w) * rest + np.sqrt(w) * flight
    return out


# --------------------------------------------------------------------------------------------------- comparison

#: Bands of the spectrum comparison: 9 logarithmically spaced bands from 1 to 90 Hz.
COMPARE_BANDS_HZ = tuple(float(f"{f:.4g}") for f in np.geomspace(1.0, 90.0, 10))


def _tail(path, parts: int = 4) -> str:
    return "/".join(Path(path).parts[-parts:])


def fit_files(imu_csv, gt_csv, **fit_options) -> MeasuredImuModel:
    """fit_model on a EuRoC imu0/data.csv and a 17-column state_groundtruth_estimate0/data.csv."""
    from linnet.sim.imu import load_real_imu
    from linnet.sim.trajectory import load_trajectory

    imu = load_real_imu(str(imu_csv), what="IMU csv")
    gt = load_trajectory(str(gt_csv))
    t, error, state = imu_error(imu.t_ns, imu.gyr, imu.acc, gt, where=str(gt_csv))
    return fit_model(t, error, state, source=f"{_tail(imu_csv)} against {_tail(gt_csv)}", **fit_options)


def band_levels(model: MeasuredImuModel, phase: str, bands=COMPARE_BANDS_HZ) -> np.ndarray:
    """(6, B) mean PSD of each axis in each band [bands[i], bands[i+1])."""
    f = model.freqs_hz
    out = np.empty((6, len(bands) - 1))
    for i, (lo, hi) in enumerate(zip(bands[:-1], bands[1:])):
        sel = (f >= lo) & (f < hi)
        if not sel.any():  # a band narrower than a bin: the bin it falls in
            sel = np.abs(f - 0.5 * (lo + hi)) == np.abs(f - 0.5 * (lo + hi)).min()
        out[:, i] = model.psd[phase][:, sel].mean(axis=1)
    return out


def compare_models(reference: MeasuredImuModel, other: MeasuredImuModel, bands=COMPARE_BANDS_HZ) -> dict:
    """Per phase: the band levels' ratio other / reference in dB (6 x B), and the standard deviations of both, in the
    bands' range and over the whole spectrum (0 to Nyquist), with their ratios (6,). Both models must be fitted the same way (same segment lengths)."""
    out = {"bands_hz": list(bands), "axes": list(AXES), "phases": {}}
    for ph in PHASES:
        ref, oth = band_levels(reference, ph, bands), band_levels(other, ph, bands)
        with np.errstate(divide="ignore", invalid="ignore"):
            db = 10.0 * np.log10(oth / ref)
        s_ref = band_std(reference.freqs_hz, reference.psd[ph], bands[0], bands[-1])
        s_oth = band_std(other.freqs_hz, other.psd[ph], bands[0], bands[-1])
        full_ref = band_std(reference.freqs_hz, reference.psd[ph], 0.0, reference.rate_hz)
        full_oth = band_std(other.freqs_hz, other.psd[ph], 0.0, other.rate_hz)
        out["phases"][ph] = {"db": db.tolist(), "max_abs_db": float(np.nanmax(np.abs(db))),
                             "std_reference": s_ref.tolist(), "std_other": s_oth.tolist(),
                             "std_ratio": (s_oth / s_ref).tolist(),
                             "std_full_reference": full_ref.tolist(), "std_full_other": full_oth.tolist(),
                             "std_full_ratio": (full_oth / full_ref).tolist(),
                             "seconds": [reference.seconds[ph], other.seconds[ph]]}
    return out
