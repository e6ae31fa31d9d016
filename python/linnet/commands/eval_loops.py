"""``linnet eval-loops RUN_DIR GROUND_TRUTH``: each loop closure's measured relative pose against the ground truth."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE, DataError, write_json_report


def _bands(ctx, param, value: str) -> tuple:
    try:
        bands = tuple(int(tok) for tok in value.split(",") if tok.strip())
    except ValueError:
        raise click.BadParameter(f"'{value}' is not a comma-separated list of inlier counts") from None
    if list(bands) != sorted(set(bands)) or any(b <= 0 for b in bands):
        raise click.BadParameter(f"'{value}': the inlier counts must be positive and increasing")
    return bands


def _mm(x) -> str:
    return "-" if x is None else f"{1000.0 * x:.1f}"


def _print_report(report: dict) -> None:
    """A plain table (readable in logs at any width): position errors in mm, rotation in deg."""
    click.echo(f"loops of {report['loops_file']} against {report['ground_truth']}")
    header = ("method", "inliers", "loops", "RMSE mm", "median", "max", "rot deg", "sigma mm", "e/sigma", ">3 sig")
    rows = []
    for g in report["groups"]:
        ratio = "-" if g["error_over_sigma_rms"] is None else f"{g['error_over_sigma_rms']:.2f}"
        rows.append((g["method"], g["inliers"], str(g["loops"]), _mm(g["position_rmse_m"]), _mm(g["position_median_m"]),
                     _mm(g["position_max_m"]), f"{g['rotation_rmse_deg']:.3f}", _mm(g["sigma_median_m"]), ratio,
                     f"{g['beyond_3_sigma']:.2f}"))
    widths = [max(len(r[k]) for r in rows + [header]) for k in range(len(header))]
    for r in [header] + rows:
        click.echo("  ".join(c.ljust(w) if k < 2 else c.rjust(w) for k, (c, w) in enumerate(zip(r, widths))))
    click.echo("position error: RMSE, median, max; rot: rotation RMSE; sigma: median edge sigma; e/sigma: RMS of the "
               "position error over its sigma (about 1.7 for well-set 3D sigmas); >3 sig: fraction beyond 3 sigmas")
    if report["worst"]:
        click.echo("largest position errors:")
        for w in report["worst"]:
            ratio = "-" if w["error_over_sigma"] is None else f"{w['error_over_sigma']:.1f}"
            click.echo(f"  {_mm(w['position_error_m'])} mm ({ratio} sigma of {_mm(w['sigma_m'])} mm), "
                       f"{w['rotation_error_deg']:.2f} deg, {w['inliers']} inliers, {w['method']}: keyframes at "
                       f"{1e-9 * w['t_new_ns']:.3f} s and {1e-9 * w['t_old_ns']:.3f} s")


@click.command("eval-loops")
@click.argument("run_dir", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.argument("ground_truth", type=click.Path(exists=True, path_type=Path))
@click.option("--t-max-diff", type=click.FloatRange(min=0.0, min_open=True), default=0.01, show_default=True,
              help="Largest time difference (s) between a keyframe stamp and the nearest ground-truth pose.")
@click.option("--bands", type=str, default="20,30", show_default=True, callback=_bands,
              help="Inlier counts that start a new band of the summary (here: < 20, 20-29, >= 30).")
@click.option("--worst", type=click.IntRange(min=0), default=5, show_default=True,
              help="List this many loops with the largest position errors.")
@click.option("--json", "json_file", type=OUTPUT_FILE, default=None,
              help="Write the summary and every loop's errors as JSON to this file.")
@click.option("--plot", "plot_file", type=OUTPUT_FILE, default=None,
              help="Write a PNG of each loop's position error over its inliers, by method, to this file.")
def COMMAND(run_dir, ground_truth, t_max_diff, bands, worst, json_file, plot_file):
    """Score RUN_DIR/loops.csv (from `linnet run` with loop closure) against GROUND_TRUTH: a trajectory file
    (EuRoC csv, TUM) or a dataset folder holding mav0/state_groundtruth_estimate0/data.csv.

    Each loop's measured relative pose of its two keyframes is compared with the ground truth's, interpolated at the
    keyframes' stamps (no alignment needed). Prints the position and rotation errors and the position error over the
    pose-graph edge's sigma, for all loops and by how they were verified and their inliers. Exit code 1 on missing or
    malformed files.
    """
    from linnet import evaluation as ev
    from linnet import loop_eval

    try:
        report = loop_eval.evaluate_run_loops(run_dir, ground_truth, t_max_diff=t_max_diff, bands=bands, worst=worst)
    except ev.InputError as e:
        raise DataError(str(e)) from None
    if not report["loops"]:
        click.echo(f"note: {report['loops_file']} holds no loop")
    else:
        _print_report(report)
    if plot_file is not None:
        from linnet import plots

        click.echo(f"plot: {plots.plot_loop_errors(report, plot_file)}")
    if json_file is not None:
        write_json_report(json_file, report)
