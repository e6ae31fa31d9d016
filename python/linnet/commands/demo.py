"""`linnet demo`: simulate a short stereo + IMU sequence, run Linnet on it, evaluate. Needs no outside data."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR


@click.command("demo")
@click.option("--out", type=OUTPUT_DIR, default=Path("runs/demo"),
              show_default=True, help="Where the simulated sequence and the results go.")
@click.option("--scene", default="room", show_default=True, help="Simulator scene (room, hall, lowtex, mixed).")
@click.option("--duration", type=float, default=30.0, show_default=True, help="Seconds of simulated motion.")
@click.option("--seed", type=int, default=1, show_default=True)
def COMMAND(out, scene, duration, seed):
    """Render a built-in figure-of-eight flight through a room (stereo + IMU, EuRoC layout), run Linnet on it and
    print the trajectory error and the real-time factor."""
    import linnet
    from linnet import sim
    from linnet.api import load_config, summarize, write_outputs

    data = out / f"sim_{scene}_{seed}_{duration:g}s"
    if not (data / "mav0" / "cam0" / "data.csv").is_file():
        click.echo(f"[demo] simulating {duration:g} s of the built-in loop trajectory in a '{scene}' scene -> {data}")
        sim.simulate("builtin:loop", scene, data, seed=seed, duration=duration)
    else:
        click.echo(f"[demo] using the cached simulated sequence {data}")
    click.echo("[demo] running Linnet (stereo + IMU, blocking mode)")
    cfg = load_config(data)
    run = linnet._linnet.run_euroc(str(data), cfg, -1, 0.0, None)
    summary = summarize(run, data)
    results = out / "result"
    write_outputs(run, summary, results)
    ape = summary.get("ape")
    click.echo(f"[demo] frames: {summary['frames']}, with pose: {summary['frames_with_pose']}, "
               f"initialised after {summary['initialisation_time_s']:.2f} s, "
               f"re-initialisations: {summary['reinitialisations']}")
    if ape:
        click.echo(f"[demo] APE RMSE (SE3, position): {ape['rmse_m']:.4f} m over {ape['pairs']} poses")
    else:
        click.echo(f"[demo] no APE: {summary.get('ape_error', 'no poses')}")
    click.echo(f"[demo] real-time factor: {summary['real_time_factor']:.3f} "
               f"(wall {summary['wall_time_s']:.1f} s / sequence {summary['sequence_duration_s']:.1f} s)")
    try:
        from linnet import evaluation, plots

        est = evaluation.load_trajectory(results / "trajectory.tum")
        gt = linnet.api.find_ground_truth(data)
        res = evaluation.ape(est, evaluation.load_trajectory(gt), align="se3", t_max_diff=0.01)
        plots.plot_ape(res, results) if hasattr(plots, "plot_ape") else None
    except Exception as e:  # plots are a bonus
        click.echo(f"[demo] (no plots: {e})")
    click.echo(f"[demo] outputs in {results}/")
