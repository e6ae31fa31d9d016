"""`linnet run DATASET`: run a EuRoC-format folder and write the trajectory, timings and a summary."""
from __future__ import annotations

import json
from pathlib import Path

import click


@click.command("run")
@click.argument("dataset", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="YAML file overriding the defaults (see `linnet config`).")
@click.option("--out", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Output folder (default: runs/<dataset name>).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override one config key, e.g. --set pipeline.use_lines=false (repeatable).")
@click.option("--max-frames", type=int, default=-1, show_default=True, help="Stop after N frames (-1: all).")
@click.option("--start", type=float, default=0.0, show_default=True, help="Skip the first S seconds of images.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def COMMAND(dataset, config_file, out, overrides, max_frames, start, quiet):
    """Run Linnet on a EuRoC folder (holding mav0/). Writes trajectory.tum, trajectory.csv, timing.csv, map.ply and
    summary.json to --out; prints the APE when the dataset has ground truth."""
    import linnet
    from linnet.api import load_config, summarize, write_outputs

    out = out or Path("runs") / dataset.resolve().name
    try:
        cfg = load_config(dataset, config_file, _overrides_yaml(overrides))
    except linnet.Error as e:
        raise click.ClickException(str(e))
    run = _run_with_progress(linnet, dataset, cfg, max_frames, start, quiet)
    summary = summarize(run, dataset)
    write_outputs(run, summary, out)
    _print_summary(summary, out)


def _overrides_yaml(overrides) -> str:
    """KEY=VALUE pairs (dotted keys) -> a nested YAML document."""
    import yaml

    tree: dict = {}
    for item in overrides:
        if "=" not in item:
            raise click.BadParameter(f"'{item}' is not KEY=VALUE", param_hint="--set")
        key, value = item.split("=", 1)
        node = tree
        parts = key.strip().split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = yaml.safe_load(value)
    return yaml.safe_dump(tree) if tree else ""


def _run_with_progress(linnet, dataset, cfg, max_frames, start, quiet):
    if quiet:
        try:
            return linnet._linnet.run_euroc(str(dataset), cfg, max_frames, start, None)
        except linnet.Error as e:
            raise click.ClickException(str(e))
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("[bold]linnet run[/bold]"), BarColumn(), MofNCompleteColumn(),
                  TimeRemainingColumn(), transient=True) as bar:
        task = bar.add_task("frames", total=None)

        def progress(done, total):
            bar.update(task, completed=done, total=total)

        try:
            return linnet._linnet.run_euroc(str(dataset), cfg, max_frames, start, progress)
        except linnet.Error as e:
            raise click.ClickException(str(e))


def _print_summary(summary: dict, out: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"linnet run: {summary['dataset']}", show_header=False)
    rows = [
        ("frames (processed / with pose)",
         f"{summary['frames']} ({summary['processed_frames']} / {summary['frames_with_pose']})"),
        ("initialisation time", f"{summary['initialisation_time_s']:.2f} s"),
        ("re-initialisations", str(summary["reinitialisations"])),
        ("wall time", f"{summary['wall_time_s']:.2f} s"),
        ("real-time factor (wall / CPU)",
         f"{summary['real_time_factor']:.3f} / {summary['cpu_real_time_factor']:.3f} "
         f"(images decoded in {summary['image_load_cpu_s']:.1f} s CPU)"),
    ]
    if "ape" in summary:
        ape = summary["ape"]
        rows.append(("APE RMSE (SE3, position)", f"{ape['rmse_m']:.4f} m over {ape['pairs']} poses"))
        rows.append(("path length (estimate / gt)",
                     f"{summary['path_length_m']:.3f} m / {summary['gt_path_length_m']:.3f} m"))
    for k, v in rows:
        table.add_row(k, v)
    Console().print(table)
    click.echo(f"outputs in {out}/ (summary.json: {json.dumps(summary.get('ape', {}).get('rmse_m'))})")
