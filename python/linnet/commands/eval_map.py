"""``linnet eval-map RUN_DIR DATASET``: the run's 3D line map against the simulator's true scene lines."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE, DataError, write_json_report


# Above this median distance of the map lines to their associated true segments (metres), most map lines stand for no
# true segment: low-texture replays give 0.02-0.03 m, the textured room and hall replays 0.27-0.47 m (stop 53).
UNMATCHED_ASSOCIATION_M = 0.1


def _fmt(value, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def _print_table(report: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    console = Console(highlight=False, markup=False)
    table = Table(title=f"line map {report['map_lines']} vs {report['true_lines']}", title_justify="left")
    table.add_column("figure", no_wrap=True)
    table.add_column("value", justify="right", no_wrap=True)
    table.add_row("map lines (total)", str(report["lines_total"]))
    gate = "" if report.get("max_sigma_m") is None else f", endpoint sigma <= {report['max_sigma_m']:g} m"
    table.add_row(f"map lines evaluated (>= {report['min_observations']} observations{gate})",
                  str(report["lines_evaluated"]))
    table.add_row("true lines associated", f"{report['true_lines_associated']} of {report['true_lines_total']}")
    table.add_row(f"true lines with a map line within {report['within_m']:g} m",
                  f"{report['true_lines_mapped']} of {report['true_lines_total']}")
    table.add_row("median angle [deg]", _fmt(report["median_angle_deg"], ".3f"))
    table.add_row("median endpoint distance [m]", _fmt(report["median_endpoint_dist_m"], ".4f"))
    table.add_row("90th percentile endpoint distance [m]", _fmt(report["p90_endpoint_dist_m"], ".4f"))
    table.add_row(f"both endpoints within {report['within_m']:g} m", _fmt(report["frac_within"], ".3f"))
    console.print(table)
    a = report["alignment"]
    console.print(f"alignment: SE3 of {a['trajectory']} onto {a['ground_truth']} from {a['pairs']} pose pairs "
                  f"(t_max_diff {a['t_max_diff_s']:g} s), APE RMSE {_fmt(a['ape_rmse_m'], '.4f')} m")


@click.command("eval-map")
@click.argument("run_dir", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.argument("dataset", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--min-observations", type=click.IntRange(min=0), default=5, show_default=True,
              help="Evaluate only map lines observed by at least this many frames.")
@click.option("--within", "within_m", type=click.FloatRange(min=0.0), default=0.05, show_default=True,
              help="Distance bound (metres) of the 'both endpoints within' fraction.")
@click.option("--max-sigma", "max_sigma_m", type=click.FloatRange(min=0.0), default=None,
              help="Evaluate only map lines whose predicted endpoint standard deviation (map_lines.csv's "
                   "endpoint_sigma) is at most this many metres.")
@click.option("--json", "json_file", type=OUTPUT_FILE, default=None,
              help="Write the figures as JSON to this file.")
def COMMAND(run_dir, dataset, min_observations, within_m, max_sigma_m, json_file):
    """Score RUN_DIR/map_lines.csv (from `linnet run`) against DATASET/sim/lines.csv (from `linnet simulate`).

    The map is brought into the ground-truth frame by the SE3 alignment of RUN_DIR/trajectory.tum onto the dataset's
    ground truth (as for the APE). Each map line is associated with the true segment nearest to its endpoints; prints
    the angle to it and the endpoint distances to its infinite line. Exit code 1 on missing or malformed files.
    """
    from linnet import evaluation as ev
    from linnet import map_eval

    try:
        report = map_eval.evaluate_run_map(run_dir, dataset, min_observations=min_observations, within_m=within_m,
                                           max_sigma_m=max_sigma_m)
    except ev.InputError as e:
        raise DataError(str(e)) from None
    _print_table(report)
    assoc = report.get("median_association_dist_m")
    if assoc is not None and assoc > UNMATCHED_ASSOCIATION_M:
        click.echo(f"note: the median map line is {assoc:.2f} m from its nearest true segment: most map lines have none "
                   "(sim/lines.csv holds the scene's geometric edges, not its texture edges: room and hall scenes), so "
                   "these figures score the association, not the map; the lowtex scene is the one to measure a line "
                   "map on")
    if report["lines_evaluated"] == 0:
        gate = "" if max_sigma_m is None else f" and an endpoint sigma of at most {max_sigma_m:g} m"
        click.echo(f"note: no map line has {min_observations} or more observations{gate}")
    if json_file is not None:
        write_json_report(json_file, report)
