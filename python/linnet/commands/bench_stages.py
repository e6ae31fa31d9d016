"""`linnet bench stages [DATASET]`: per-stage median and p95 ms of a run (front-end, back-end, total)."""
from __future__ import annotations

import json
from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE


def stage_table(timing_csv: Path) -> dict:
    import numpy as np

    data = np.genfromtxt(timing_csv, delimiter=",", comments="#")
    data = np.atleast_2d(data)
    cols = {"frontend": 1, "backend": 2, "total": 3, "points": 4, "lines": 5}
    if data.shape[1] >= 14:  # CPU-time columns (thread CPU clock): unaffected by other load on the core
        cols.update({"points_cpu": 11, "lines_cpu": 12, "backend_cpu": 13})
    out = {}
    for name, c in cols.items():
        v = data[:, c]
        out[name] = {"median_ms": float(np.median(v)), "p95_ms": float(np.percentile(v, 95)),
                     "max_ms": float(np.max(v)), "frames": int(v.size)}
    return out


@click.command("stages")
@click.argument("dataset", required=False, type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--duration", type=float, default=20.0, show_default=True,
              help="Without DATASET: seconds of the built-in simulated sequence.")
@click.option("--json", "json_out", type=OUTPUT_FILE, help="Write the table as JSON.")
def COMMAND(dataset, duration, json_out):
    """Run Linnet on DATASET (default: a simulated room sequence) and print per-stage median / p95 ms."""
    import linnet
    from linnet.api import load_config, summarize, write_outputs

    if dataset is None:
        from linnet import sim

        dataset = Path("runs/bench") / f"sim_room_{duration:g}s"
        if not (dataset / "mav0" / "cam0" / "data.csv").is_file():
            sim.simulate("builtin:loop", "room", dataset, seed=1, duration=duration)
    cfg = load_config(dataset)
    run = linnet._linnet.run_euroc(str(dataset), cfg, -1, 0.0, None)
    summary = summarize(run, dataset)
    out = Path("runs/bench") / ("stages_" + Path(dataset).resolve().name)
    write_outputs(run, summary, out)
    table = stage_table(out / "timing.csv")
    click.echo(f"| stage | median ms | p95 ms | max ms |   ({dataset}, {table['total']['frames']} frames, "
               f"real-time factor wall {summary['real_time_factor']:.3f}, CPU {summary['cpu_real_time_factor']:.3f})")
    click.echo("|---|---|---|---|")
    for name, s in table.items():
        click.echo(f"| {name} | {s['median_ms']:.2f} | {s['p95_ms']:.2f} | {s['max_ms']:.2f} |")
    n = max(1, table["total"]["frames"])
    click.echo(f"| image decode (mean CPU, both images) | {1e3 * summary['image_load_cpu_s'] / n:.2f} | | |")
    if json_out:
        json_out.write_text(json.dumps({"stages": table, "summary": summary}, indent=2) + "\n")
