"""`linnet bench stages [DATASET]`: per-stage median and p95 ms of a run (wall and CPU time, each stage's share of the
frame's CPU time, the back-end's line steps and solve)."""
from __future__ import annotations

import json
from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE


#: timing.csv columns (0-based) of the per-stage times; the *_cpu ones are thread CPU time (unaffected by other load).
WALL_COLUMNS = {"frontend": 1, "backend": 2, "total": 3, "points": 4, "lines": 5}
CPU_COLUMNS = {"points_cpu": 11, "lines_cpu": 12, "backend_cpu": 13}
#: The loop closer's CPU time (estimator thread, after the estimator), in runs written since loop closure exists.
LOOP_CPU_COLUMN = 18
#: Parts of the back-end (wall time on the estimator thread, which does nothing else): line steps and the solve.
BACKEND_PARTS = {"line_backend": 14, "solver": 15}
#: The process's resident set size after each frame, MB (runs written since it exists).
RSS_COLUMN = 19


def memory_growth(timing_csv: Path, after_s: float = 60.0) -> dict | None:
    """Resident set size after `after_s` seconds of data and at the end of a run (from timing.csv), MB; None for
    runs without the column or shorter than `after_s`."""
    import numpy as np

    data = np.atleast_2d(np.genfromtxt(timing_csv, delimiter=",", comments="#"))
    if data.shape[1] <= RSS_COLUMN:
        return None
    t = (data[:, 0] - data[0, 0]) * 1e-9
    if t[-1] <= after_s:
        return None
    early = float(data[np.searchsorted(t, after_s), RSS_COLUMN])
    end = float(data[-1, RSS_COLUMN])
    return {"after_s": after_s, "rss_after_mb": early, "end_s": float(t[-1]), "rss_end_mb": end,
            "growth": end / early - 1.0 if early > 0 else float("nan")}


def _stats(v) -> dict:
    import numpy as np

    return {"median_ms": float(np.median(v)), "p95_ms": float(np.percentile(v, 95)), "max_ms": float(np.max(v)),
            "mean_ms": float(np.mean(v)), "frames": int(v.size)}


def stage_table(timing_csv: Path) -> dict:
    """Per-stage statistics of a run's timing.csv: wall stages, CPU stages (with each one's share of the frame's CPU
    time) and the back-end's parts."""
    import numpy as np

    data = np.atleast_2d(np.genfromtxt(timing_csv, delimiter=",", comments="#"))
    out = {name: _stats(data[:, c]) for name, c in WALL_COLUMNS.items()}
    if data.shape[1] > max(CPU_COLUMNS.values()):
        columns = dict(CPU_COLUMNS)
        if data.shape[1] > LOOP_CPU_COLUMN:
            columns["loop_cpu"] = LOOP_CPU_COLUMN
        cpu_total = sum(data[:, c] for c in columns.values())
        for name, c in columns.items():
            out[name] = dict(_stats(data[:, c]), share=float(np.sum(data[:, c]) / max(np.sum(cpu_total), 1e-12)))
        out["frame_cpu"] = dict(_stats(cpu_total), share=1.0)
    if data.shape[1] > max(BACKEND_PARTS.values()):
        for name, c in BACKEND_PARTS.items():
            out[name] = _stats(data[:, c])
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
    click.echo(f"{dataset}: {table['total']['frames']} frames, real-time factor wall "
               f"{summary['real_time_factor']:.3f}, CPU {summary['cpu_real_time_factor']:.3f} (all threads, image "
               "decoding included)")
    click.echo("| stage | median ms | p95 ms | max ms | share of frame CPU |")
    click.echo("|---|---|---|---|---|")
    for name, s in table.items():
        share = f"{100 * s['share']:.0f} %" if "share" in s else ""
        click.echo(f"| {name} | {s['median_ms']:.2f} | {s['p95_ms']:.2f} | {s['max_ms']:.2f} | {share} |")
    n = max(1, table["total"]["frames"])
    click.echo(f"| image decode (mean CPU, both images) | {1e3 * summary['image_load_cpu_s'] / n:.2f} | | | |")
    if "frame_cpu" in table:
        f = table["frame_cpu"]
        click.echo(f"frame CPU p95 / median: {f['p95_ms'] / max(f['median_ms'], 1e-9):.2f} (points, lines and "
                   "back-end threads; `make profile` for a per-function profile)")
    memory = memory_growth(out / "timing.csv")
    if memory is not None:
        click.echo(f"resident set size: {memory['rss_after_mb']:.1f} MB after {memory['after_s']:g} s of data, "
                   f"{memory['rss_end_mb']:.1f} MB after {memory['end_s']:.0f} s ({100 * memory['growth']:+.1f} %)")
    if json_out:
        json_out.write_text(json.dumps({"stages": table, "summary": summary, "memory": memory}, indent=2) + "\n")
