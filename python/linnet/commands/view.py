"""``linnet view RUN_DIR``: the trajectory, aligned ground truth and point-and-line map in rerun."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE


class ViewInputError(click.ClickException):
    """Unreadable run folder or files: one line on stderr, exit code 1 (a data error)."""

    exit_code = 1


@click.command("view")
@click.argument("run_dir", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--gt", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="Ground truth (TUM or EuRoC csv); default: the dataset's, found through RUN_DIR/summary.json.")
@click.option("--save", type=OUTPUT_FILE, default=None,
              help="Write a rerun recording (.rrd) instead of opening the viewer (works headless).")
def COMMAND(run_dir, gt, save):
    """Show a run folder (from `linnet run`) in the rerun viewer: estimate, SE3-aligned ground truth, map.ply
    (line segments from map_lines.csv when map.ply has none).

    Needs the optional rerun-sdk package (pip install 'linnet[viewer]').
    """
    from linnet import evaluation as ev
    from linnet import viewer

    try:
        view = viewer.load_run(run_dir, gt=gt)
    except ev.InputError as e:
        raise ViewInputError(str(e)) from None
    for note in view.notes:
        click.echo(f"note: {note}")
    try:
        viewer.show_run(view, save=save)
    except viewer.RerunMissing as e:
        raise click.ClickException(str(e)) from None
    m = view.map
    summary = f"{len(view.estimate)} poses"
    if m is not None:
        summary += f", {len(m.points)} map points, {len(m.segments)} map lines"
    if view.ape_rmse_m is not None:
        summary += f", APE RMSE {view.ape_rmse_m:.4f} m (SE3)"
    click.echo(f"{summary}; " + (f"recording saved to {save}" if save else "viewer spawned"))
