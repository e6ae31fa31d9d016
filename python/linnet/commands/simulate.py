"""``linnet simulate``: replay a trajectory through a procedural scene into a EuRoC ASL dataset."""
from __future__ import annotations

import json

import click

from linnet.commands.params import OUTPUT_DIR, OUTPUT_FILE, POSITIVE_SECONDS, SECONDS
from linnet.sim.imu import IMU_NOISE_KEYWORDS
from linnet.sim.realism import CALIB_ERRORS, REALISM_LEVELS, REALISM_PRESETS
from linnet.sim.scene import SCENES


def _check_imu_noise(ctx, param, value):
    """A keyword or an existing file (what the file holds is checked when it is read: exit code 1)."""
    from pathlib import Path

    if value is None or value in IMU_NOISE_KEYWORDS or Path(value).is_file():
        return value
    raise click.BadParameter(f"'{value}' is neither {', '.join(IMU_NOISE_KEYWORDS)} nor an existing file")


@click.command("simulate")
@click.option("--trajectory", "trajectory", required=True, metavar="GT",
              help="Ground-truth trajectory: TUM (t x y z qx qy qz qw) or EuRoC csv (17 or 8 columns), body = IMU; "
                   "or builtin:loop (a 30 s figure-eight in a room).")
@click.option("--scene", type=click.Choice(SCENES), default="room", show_default=True, help="Procedural scene.")
@click.option("--out", "out_dir", required=True, type=OUTPUT_DIR, help="Output folder (gets mav0/).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the scene, the IMU noise and the images.")
@click.option("--start", type=SECONDS, default=0.0, show_default=True, help="Seconds to skip into the trajectory.")
@click.option("--duration", type=POSITIVE_SECONDS, default=None, help="Seconds to simulate (default: to the end).")
@click.option("--realism", type=click.Choice(REALISM_LEVELS), default="easy", show_default=True,
              help="Preset: easy = clean sensors; hard = --blur --exposure-changes --imu-noise measured "
                   "--calib-error typical --time-offset-ms 3. Options given explicitly override the preset.")
@click.option("--imu-noise", default=None, metavar="euroc|none|measured|FILE", callback=_check_imu_noise,
              help="IMU noise: EuRoC ADIS16448 white-noise densities, none, measured (spectra of the real V1_01_easy "
                   "flight, vibration included), a model from linnet sim fit-imu, or a YAML with Kalibr's noise keys. "
                   "[preset: easy euroc, hard measured]")
@click.option("--real-imu", type=click.Path(exists=True, dir_okay=False), default=None,
              help="Use this EuRoC imu0/data.csv instead of a synthetic IMU (images still rendered from GT).")
@click.option("--blur/--no-blur", default=None, help="Motion blur (sub-frame averaging over a 10 ms exposure).")
@click.option("--exposure-changes/--no-exposure-changes", default=None, help="Auto-exposure-like gain changes.")
@click.option("--calib-error", type=click.Choice(CALIB_ERRORS), default=None,
              help="Perturb the written calibration (intrinsics, distortion, extrinsics) by typical Kalibr errors; "
                   "images use the true one. [preset: easy none, hard typical]")
@click.option("--time-offset-ms", type=float, default=None,
              help="Constant offset added to every written camera stamp, ms. [preset: easy 0, hard 3]")
@click.option("--stamp-jitter-us", type=float, default=None,
              help="Gaussian jitter (std, us) added to every written camera stamp. [preset: 0]")
@click.option("--json", "json_file", type=OUTPUT_FILE, default=None,
              help="Also write the summary (frames, timings, fit residual) to this JSON file.")
def simulate_command(trajectory, scene, out_dir, seed, start, duration, realism, imu_noise, real_imu, blur,
                     exposure_changes, calib_error, time_offset_ms, stamp_jitter_us, json_file):
    """Render a EuRoC-like stereo + IMU sequence with ground truth from a trajectory and a scene."""
    given = {"blur": blur, "exposure_changes": exposure_changes, "imu_noise": imu_noise, "calib_error": calib_error,
             "time_offset_ms": time_offset_ms, "stamp_jitter_us": stamp_jitter_us}
    settings = {k: (v if v is not None else REALISM_PRESETS[realism][k]) for k, v in given.items()}
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    from linnet.sim import InputError, simulate

    with Progress(TextColumn("[bold]simulate[/] {task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total} frames"), TimeRemainingColumn(), transient=True) as bar:
        task = bar.add_task(f"{scene}", total=None)

        def progress(done, total):
            bar.update(task, completed=done, total=total)

        try:
            summary = simulate(trajectory, scene, out_dir, seed=seed, start=start, duration=duration,
                               real_imu=real_imu, progress=progress, **settings)
        except InputError as e:  # a file or value the simulator cannot use: a data error (exit code 1)
            raise click.ClickException(str(e)) from None
    fit = summary["fit"]
    click.echo(f"wrote {summary['out_dir']}: {summary['frames']} stereo frames, {summary['duration_s']:.1f} s, "
               f"rendered in {summary['render_s']:.1f} s ({summary['stereo_fps']:.1f} stereo frames/s); "
               f"scene {scene}: {summary['scene']['quads']} quads, {summary['scene']['lines']} lines, "
               f"{summary['scene']['points']} points; fit residual {fit['position_rms_m'] * 1000:.2f} mm / "
               f"{fit['rotation_rms_deg']:.3f} deg RMS")
    if json_file:
        with open(json_file, "w", encoding="utf-8") as f:
            json.dump(summary, f, indent=2, sort_keys=True)


COMMAND = simulate_command
