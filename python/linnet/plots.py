"""PNG plots of an evaluation: top view, error over time, x/y/z over time.

Figures are built on matplotlib's object API with the Agg canvas (no pyplot state, no display needed). The PNG
metadata carries no software version or date, so the same inputs give the same bytes with the same matplotlib.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from linnet.evaluation import ErrorResult, Trajectory

__all__ = ["PlotOptions", "plot_top_view", "plot_error_over_time", "plot_xyz", "plot_all", "plot_ape",
           "plot_loop_errors"]


@dataclass
class PlotOptions:
    """Look of the PNG plots."""

    dpi: int = 120  # dots per inch of the PNG
    width_in: float = 7.0  # figure width, inches
    height_in: float = 5.5  # figure height, inches (x/y/z plot: per panel x 3 / 2)
    colormap: str = "viridis"  # matplotlib colormap for the per-pose error
    gt_color: str = "0.45"  # ground truth line colour (matplotlib colour spec)
    est_color: str = "tab:blue"  # estimate line colour when not coloured by error

    def visit(self, visitor) -> None:
        """Options protocol (core/options.h): hand every field with its unit to ``visitor(name, value, doc)``."""
        visitor("dpi", self.dpi, "dots per inch")
        visitor("width_in", self.width_in, "inches")
        visitor("height_in", self.height_in, "inches")
        visitor("colormap", self.colormap, "matplotlib colormap")
        visitor("gt_color", self.gt_color, "matplotlib colour")
        visitor("est_color", self.est_color, "matplotlib colour")


def _figure(options: PlotOptions, height_in: Optional[float] = None):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(options.width_in, height_in or options.height_in), dpi=options.dpi, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # No "Software" (version) key in the PNG: deterministic bytes.
    fig.savefig(path, format="png", metadata={"Software": None})
    return path


def _seconds_from(t_ns: np.ndarray, t0_ns: int) -> np.ndarray:
    return (np.asarray(t_ns, dtype=np.int64) - t0_ns).astype(np.float64) * 1e-9


def _break_gaps(t: np.ndarray, y: np.ndarray, factor: float = 5.0):
    """Insert NaN rows where the time step exceeds ``factor`` x the median step, so lines do not bridge gaps."""
    if t.shape[0] < 3:
        return t, y
    dt = np.diff(t)
    gaps = np.flatnonzero(dt > factor * np.median(dt))
    if gaps.size == 0:
        return t, y
    t_out = np.insert(t, gaps + 1, np.nan)
    y_out = np.insert(np.asarray(y, dtype=np.float64), gaps + 1, np.nan, axis=0)
    return t_out, y_out


def plot_top_view(
    result: ErrorResult,
    path,
    gt_full: Optional[Trajectory] = None,
    color_by_error: bool = True,
    options: Optional[PlotOptions] = None,
) -> Path:
    """Top view (x-y, metres) of the aligned estimate against the ground truth.

    gt_full: draw this (whole) ground truth instead of only the associated poses. color_by_error: colour the estimate
    by the per-pose error (APE results only; an RPE result has fewer errors than poses).
    """
    from matplotlib.collections import LineCollection

    options = options or PlotOptions()
    fig = _figure(options)
    ax = fig.add_subplot(1, 1, 1)
    gt = gt_full if gt_full is not None else result.reference
    est = result.estimate.positions
    ax.plot(gt.positions[:, 0], gt.positions[:, 1], "--", color=options.gt_color, lw=1.2, label="ground truth")
    if color_by_error and result.errors.shape[0] == est.shape[0] and est.shape[0] >= 2:
        segments = np.stack([est[:-1, :2], est[1:, :2]], axis=1)
        seg_err = 0.5 * (result.errors[:-1] + result.errors[1:])
        lc = LineCollection(segments, cmap=options.colormap, linewidths=2.0, label="estimate")
        lc.set_array(seg_err)
        lc.set_clim(float(result.errors.min()), float(result.errors.max()))
        ax.add_collection(lc)
        cbar = fig.colorbar(lc, ax=ax)
        cbar.set_label(f"{result.metric.upper()} [{result.unit}]")
    else:
        ax.plot(est[:, 0], est[:, 1], "-", color=options.est_color, lw=1.5, label="estimate")
    ax.plot(gt.positions[0, 0], gt.positions[0, 1], "o", color=options.gt_color, ms=5)
    ax.plot(est[0, 0], est[0, 1], "o", color=options.est_color, ms=5, label="start")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.legend(loc="best", fontsize="small")
    ax.set_title(
        f"top view, {result.align} aligned - {result.metric.upper()} RMSE {result.rmse:.4f} {result.unit}"
        f" ({result.pairs} pairs)",
        fontsize="medium",
    )
    return _save(fig, path)


def plot_error_over_time(result: ErrorResult, path, options: Optional[PlotOptions] = None) -> Path:
    """Per-pair error over time (s since the first associated pose) with RMSE / mean / median lines."""
    options = options or PlotOptions()
    fig = _figure(options, options.height_in * 0.7)
    ax = fig.add_subplot(1, 1, 1)
    t = _seconds_from(result.t_ns, int(result.estimate.t_ns[0]))
    ax.plot(*_break_gaps(t, result.errors), ".-", ms=1.5, color=options.est_color, lw=1.0,
            label=result.metric.upper())
    ax.axhline(result.rmse, color="tab:red", lw=1.0, label=f"rmse {result.rmse:.4f}")
    ax.axhline(result.mean, color="tab:orange", lw=1.0, ls="--", label=f"mean {result.mean:.4f}")
    ax.axhline(result.median, color="tab:green", lw=1.0, ls=":", label=f"median {result.median:.4f}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"{result.metric.upper()} ({result.pose_relation}) [{result.unit}]")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, lw=0.4, alpha=0.6)
    ax.legend(loc="upper left", fontsize="small")
    title = f"{result.metric.upper()} over time, {result.align} aligned"
    if result.metric == "rpe":
        title += f", delta {result.delta:g} {result.delta_unit}"
    ax.set_title(title, fontsize="medium")
    return _save(fig, path)


def plot_xyz(
    result: ErrorResult, path, gt_full: Optional[Trajectory] = None, options: Optional[PlotOptions] = None
) -> Path:
    """Three panels: x, y, z (m) over time of the aligned estimate and the ground truth."""
    options = options or PlotOptions()
    fig = _figure(options, options.height_in * 1.5)
    axes = fig.subplots(3, 1, sharex=True)
    gt = gt_full if gt_full is not None else result.reference
    t0 = int(result.estimate.t_ns[0])
    t_est, p_est = _break_gaps(_seconds_from(result.estimate.t_ns, t0), result.estimate.positions)
    t_gt, p_gt = _break_gaps(_seconds_from(gt.t_ns, t0), gt.positions)
    for i, (ax, label) in enumerate(zip(axes, "xyz")):
        ax.plot(t_gt, p_gt[:, i], "--", color=options.gt_color, lw=1.2, label="ground truth")
        ax.plot(t_est, p_est[:, i], "-", color=options.est_color, lw=1.0, label="estimate")
        ax.set_ylabel(f"{label} [m]")
        ax.grid(True, lw=0.4, alpha=0.6)
    axes[0].legend(loc="best", fontsize="small")
    axes[0].set_title(f"position over time, {result.align} aligned", fontsize="medium")
    axes[-1].set_xlabel("time [s]")
    return _save(fig, path)


def plot_all(
    ape_result: ErrorResult,
    out_dir,
    rpe_result: Optional[ErrorResult] = None,
    gt_full: Optional[Trajectory] = None,
    options: Optional[PlotOptions] = None,
) -> list:
    """Write top_view.png, ape_over_time.png, xyz.png (and rpe_over_time.png) into out_dir; return their paths."""
    out = Path(out_dir)
    written = [
        plot_top_view(ape_result, out / "top_view.png", gt_full=gt_full, options=options),
        plot_error_over_time(ape_result, out / "ape_over_time.png", options=options),
        plot_xyz(ape_result, out / "xyz.png", gt_full=gt_full, options=options),
    ]
    if rpe_result is not None:
        written.append(plot_error_over_time(rpe_result, out / "rpe_over_time.png", options=options))
    return written


def plot_ape(ape_result: ErrorResult, out_dir, gt_full: Optional[Trajectory] = None) -> list:
    """The APE plots (top view, error over time, x/y/z) into out_dir; same as plot_all without RPE."""
    return plot_all(ape_result, out_dir, gt_full=gt_full)


def plot_imu_spectra(models: dict, path, options: Optional[PlotOptions] = None) -> Path:
    """PSD of the IMU error per axis (2 x 3 panels: gyroscope, accelerometer), one curve per (label, phase).
    models: label -> MeasuredImuModel (linnet.sim.imu_model), e.g. {"real": fitted, "simulated": refitted}."""
    from linnet.sim.imu_model import AXES, PHASES

    options = options or PlotOptions()
    fig = _figure(options, height_in=options.height_in * 1.2)
    axes = fig.subplots(2, 3, sharex=True)
    styles = {"rest": ":", "flight": "-"}
    for k, name in enumerate(AXES):
        ax = axes[k // 3][k % 3]
        for j, (label, model) in enumerate(models.items()):
            for ph in PHASES:
                f = model.freqs_hz
                sel = f > 0
                ax.semilogy(f[sel], model.psd[ph][k][sel], styles[ph], color=f"C{j}", lw=0.8,
                            label=f"{label}, {ph}")
        ax.set_title(name, fontsize=9)
        ax.grid(True, which="both", lw=0.3)
        if k // 3 == 1:
            ax.set_xlabel("frequency [Hz]")
    axes[0][0].set_ylabel("PSD [(rad/s)$^2$/Hz]")
    axes[1][0].set_ylabel("PSD [(m/s$^2$)$^2$/Hz]")
    axes[0][0].legend(fontsize=7)
    return _save(fig, path)


def plot_loop_errors(report: dict, path, options: Optional[PlotOptions] = None) -> Path:
    """Loop closures against the ground truth (``linnet.loop_eval.evaluate_run_loops``' report): each loop's position
    error over its PnP inliers, one colour per verification method, with its edge's sigma (x) and 3 sigmas (line)."""
    options = options or PlotOptions()
    fig = _figure(options)
    ax = fig.subplots()
    loops = report["loops"]
    for j, method in enumerate(sorted({e["method"] for e in loops})):
        mine = [e for e in loops if e["method"] == method]
        inliers = np.array([e["inliers"] for e in mine], dtype=float)
        ax.scatter(inliers, [1000.0 * e["position_error_m"] for e in mine], s=14, color=f"C{j}",
                   label=f"{method} ({len(mine)})")
        ax.scatter(inliers, [1000.0 * e["sigma_m"] for e in mine], s=10, marker="x", color=f"C{j}", alpha=0.5)
    if loops:
        n = np.array(sorted({e["inliers"] for e in loops}), dtype=float)
        sigma = [np.median([3000.0 * e["sigma_m"] for e in loops if e["inliers"] == k]) for k in n]
        ax.plot(n, sigma, color="0.4", lw=0.8, label="3 x median sigma")
    ax.set_xlabel("PnP inliers")
    ax.set_ylabel("position error [mm] (x: the edge's sigma)")
    ax.set_yscale("log")
    from matplotlib.ticker import FormatStrFormatter

    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))  # 20, 50, not 2 x 10^1
    ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
    ax.grid(True, which="both", lw=0.3)
    ax.set_title(f"{len(loops)} loops against the ground truth", fontsize=10)
    if loops:
        ax.legend(fontsize=8)
    return _save(fig, path)
