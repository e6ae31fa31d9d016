"""``linnet eval EST GT``: APE and RPE of a trajectory against ground truth, with optional plots and JSON."""
from __future__ import annotations

import math
from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR, OUTPUT_FILE, DataError, write_json_report
from linnet import evaluation as ev


def _rpe_or_reason(est, gt, delta, align, t_max_diff, relation):
    try:
        return ev.rpe(est, gt, delta=delta, delta_unit="m", align=align, t_max_diff=t_max_diff,
                      pose_relation=relation), None
    except ev.InputError as e:
        return None, str(e)


def _json_number(x):
    return x if (not isinstance(x, float) or math.isfinite(x)) else None


def _report(est_path, gt_path, est, gt, ape_res, rpe_res, rpe_reason) -> dict:
    ape_stats = ape_res.stats()
    return {
        "estimate": str(est_path),
        "ground_truth": str(gt_path),
        "estimate_poses": len(est),
        "ground_truth_poses": len(gt),
        "estimate_path_length_m": ev.path_length(est),
        "ground_truth_path_length_m": ev.path_length(gt),
        "associated_ground_truth_path_length_m": ev.path_length(ape_res.reference),
        "ground_truth_over_estimate_path_length_m": ev.path_length(_gt_over_estimate(gt, est, ape_res)),
        "ape": {k: _json_number(v) for k, v in ape_stats.items()},
        "rpe": None if rpe_res is None else {k: _json_number(v) for k, v in rpe_res.stats().items()},
        "rpe_error": rpe_reason,
    }


def _gt_over_estimate(gt, est, ape_res):
    """The ground truth over the estimate's time span (plus the association tolerance): what plots and path lengths
    compare the estimate with, rather than a whole flight the estimate covers a part of."""
    margin = int(round(ape_res.t_max_diff_s * 1e9))
    return ev.time_slice(gt, int(est.t_ns[0]) - margin, int(est.t_ns[-1]) + margin)


def _orientation_notes(gt, ape_relation: str, rpe_relation: str) -> list:
    """Warn when the ground truth has no orientation (all identity, e.g. a Leica prism) but a relation uses it."""
    import numpy as np

    if not np.allclose(np.abs(gt.quaternions_wxyz[:, 0]), 1.0, atol=1e-12):
        return []
    notes = []
    if ape_relation not in ("trans_part", "point_distance"):
        notes.append(f"the ground truth has identity orientations only: APE {ape_relation} is not meaningful")
    if rpe_relation != "point_distance":
        notes.append(f"the ground truth has identity orientations only: RPE {rpe_relation} compares relative motions "
                     "in body frames it does not know; use --rpe-relation point_distance")
    return notes


def _print_table(report: dict, ape_res, rpe_res, rpe_reason) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False, markup=False)
    table = Table(title=f"{report['estimate']} vs {report['ground_truth']}", title_justify="left")
    table.add_column("metric", no_wrap=True)
    for col in ("rmse", "mean", "median", "max", "pairs"):
        table.add_column(col, justify="right", no_wrap=True)
    rows = [("APE", ape_res)]
    if rpe_res is not None:
        rows.append(("RPE", rpe_res))
    for label, res in rows:
        name = f"{label} [{res.unit}]"
        if res.metric == "rpe":
            name += f" per {res.delta:g} {res.delta_unit}"
        table.add_row(name, *(f"{getattr(res, k):.6f}" for k in ("rmse", "mean", "median", "max")),
                      str(res.pairs))
    console.print(table)
    a = ape_res
    relations = f"APE {a.pose_relation}" + (f", RPE {rpe_res.pose_relation}" if rpe_res is not None else "")
    console.print(f"{relations}; align {a.align} (scale {a.scale:.6f}); t_max_diff {a.t_max_diff_s:g} s")
    console.print(f"path length: estimate {report['estimate_path_length_m']:.3f} m, ground truth over the estimate's "
                  f"span {report['ground_truth_over_estimate_path_length_m']:.3f} m "
                  f"(whole file {report['ground_truth_path_length_m']:.3f} m)")
    if rpe_res is None:
        console.print(f"RPE not computed: {rpe_reason}")


@click.command("eval")
@click.argument("est", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.argument("gt", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--align", type=click.Choice(ev.ALIGNMENTS), default="se3", show_default=True,
              help="Alignment of the estimate to the ground truth (sim3 for monocular scale).")
@click.option("--t-max-diff", type=click.FloatRange(min=0.0), default=0.01, show_default=True,
              help="Largest time difference of an associated pose pair, seconds.")
@click.option("--pose-relation", type=click.Choice(tuple(ev.POSE_RELATIONS)), default="trans_part",
              show_default=True, help="APE pose relation (trans_part: position error in metres).")
@click.option("--rpe-delta", type=click.FloatRange(min=0.0, min_open=True), default=1.0, show_default=True,
              help="RPE pair distance, metres of travelled path.")
@click.option("--rpe-relation", type=click.Choice(tuple(ev.POSE_RELATIONS)), default="trans_part",
              show_default=True, help="RPE pose relation.")
@click.option("--plot", "plot_dir", type=OUTPUT_DIR, default=None,
              help="Write PNG plots (top view, error over time, x/y/z) into this directory.")
@click.option("--json", "json_file", type=OUTPUT_FILE, default=None,
              help="Write the numbers as JSON to this file.")
def eval_command(est, gt, align, t_max_diff, pose_relation, rpe_delta, rpe_relation, plot_dir, json_file):
    """Evaluate the trajectory EST against the ground truth GT (each TUM or EuRoC csv, detected from the content).

    Prints APE (absolute pose error after alignment) and RPE (relative pose error over RPE_DELTA metres) computed
    with evo; exit code 1 on unreadable or non-overlapping inputs, 2 on a usage error.
    """
    try:
        est_traj = ev.load_trajectory(est)
        gt_traj = ev.load_trajectory(gt)
        ape_res = ev.ape(est_traj, gt_traj, align=align, t_max_diff=t_max_diff, pose_relation=pose_relation)
    except ev.InputError as e:
        raise DataError(str(e)) from None
    rpe_res, rpe_reason = _rpe_or_reason(est_traj, gt_traj, rpe_delta, align, t_max_diff, rpe_relation)
    report = _report(est, gt, est_traj, gt_traj, ape_res, rpe_res, rpe_reason)
    report["notes"] = _orientation_notes(gt_traj, pose_relation, rpe_relation)
    _print_table(report, ape_res, rpe_res, rpe_reason)
    for note in report["notes"]:
        click.echo(f"note: {note}")
    if plot_dir is not None:
        from linnet import plots

        written = plots.plot_all(ape_res, plot_dir, rpe_result=rpe_res,
                                 gt_full=_gt_over_estimate(gt_traj, est_traj, ape_res))
        report["plots"] = [str(p) for p in written]
        click.echo(f"plots: {', '.join(str(p) for p in written)}")
    if json_file is not None:
        write_json_report(json_file, report)


COMMAND = eval_command
