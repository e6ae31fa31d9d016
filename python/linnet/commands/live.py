"""`linnet live --udp PORT`: run Linnet in real time on the stereo-IMU sensor module's UDP stream."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR, POSITIVE_SECONDS, key_values


#: Camera rate of the sensor module (thesis: 20 Hz), for a Kalibr camchain, which does not hold it.
MODULE_RATE_HZ = 20.0


@click.command("live")
@click.option("--udp", "port", type=click.IntRange(0, 65535), required=True, help="UDP port to listen on.")
@click.option("--host", default="127.0.0.1", show_default=True, help="IPv4 address to listen on (0.0.0.0: all).")
@click.option("--calib", "calib_files", multiple=True, type=click.Path(exists=True, path_type=Path), metavar="FILE",
              help="Calibration: Kalibr camchain (+ imu.yaml), or a EuRoC folder's sensor.yaml files; or give the "
                   "cam0 / cam1 / imu sections in --config.")
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="YAML file overriding the defaults (its sensor section: W, H, IMU ranges, driver policies).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", callback=key_values,
              help="Override one config key (repeatable).")
@click.option("--out", type=OUTPUT_DIR, default=Path("runs") / "live", show_default=True,
              help="Output folder: the `linnet run` outputs, with the driver counters in summary.json.")
@click.option("--record", type=OUTPUT_DIR, default=None, help="Also write the stream as a EuRoC folder here.")
@click.option("--duration", type=POSITIVE_SECONDS, default=None,
              help="Stop after this many seconds of stream (default: when it goes idle, or Ctrl-C).")
@click.option("--quiet", is_flag=True, help="No status line.")
def COMMAND(port, host, calib_files, config_file, overrides, out, record, duration, quiet):
    """Run the system in real-time mode on the sensor module's stream (frames it cannot take in time are dropped and
    counted), with a status line; stops after --duration, when the stream goes idle (sensor.idle_timeout_s) or on
    Ctrl-C, and writes the outputs. Exit code 3 when it did not track."""
    import linnet
    from linnet.api import config_value, summarize, write_outputs
    from linnet.commands.run import EXIT_TRACKING_FAILED
    from linnet.commands.sensor import sensor_config

    try:
        base = _live_calibration(calib_files, config_file)
        cfg = sensor_config(config_file, overrides, base=base)
        given = {item.partition("=")[0].strip() for item in overrides}
        for key, cam_key in (("sensor.width", "width"), ("sensor.height", "height")):
            if key not in given and not _config_sets(config_file, key):
                cfg.set(key, config_value(cfg, f"cam0.{cam_key}"))  # the module sends the calibrated cameras' images
        status = _StatusLine(quiet)
        result = linnet._linnet.run_live(cfg, host=host, port=port, duration_s=-1.0 if duration is None else duration,
                                         record_dir=str(record) if record else "", run_system=True,
                                         on_ready=lambda p: click.echo(f"listening on udp://{host}:{p}", err=True),
                                         status=status)
        status.close()
    except linnet.Error as e:
        raise click.ClickException(str(e)) from None
    counters = result["counters"]
    run = result["summary"]
    if run is None:
        raise click.ClickException(f"no frame was received on udp://{host}:{port} ({result['end_reason']}; "
                                   f"{counters['packets']} packets)")
    summary = summarize(run, None)
    summary["input"] = f"udp://{host}:{port}"
    summary["driver"] = counters
    summary["end_reason"] = result["end_reason"]
    write_outputs(run, summary, out)
    for warning in run.warnings:
        click.echo(f"linnet live: warning: {warning}", err=True)
    lost = counters["lost_rows_cam0"] + counters["lost_rows_cam1"]
    click.echo(f"{summary['frames']} frames ({summary['dropped_frames']} dropped by the system, "
               f"{counters['frames_dropped']} incomplete dropped by the driver), {lost} lost rows, "
               f"{counters['imu_samples']} IMU samples; driver CPU: receive {counters['receive_cpu_s']:.2f} s, parse "
               f"{counters['parse_cpu_s']:.2f} s; ended: {result['end_reason']}; outputs in {out}/")
    if summary["status"] != "ok":
        for problem in summary["problems"]:
            click.echo(f"linnet live: tracking failed: {problem}", err=True)
        raise click.exceptions.Exit(EXIT_TRACKING_FAILED)


def _live_calibration(calib_files, config_file):
    """The --calib config (None: the --config file holds the calibration)."""
    from linnet.api import holds_calibration
    from linnet.commands.run import calibration_config

    if calib_files:
        return calibration_config(calib_files, lambda: MODULE_RATE_HZ)
    if config_file is not None and holds_calibration(config_file):
        return None
    raise click.UsageError("no calibration: give --calib (Kalibr files or a EuRoC folder) or a --config with "
                           "cam0 / cam1 / imu sections")


def _config_sets(config_file, dotted) -> bool:
    if config_file is None:
        return False
    import yaml

    node = yaml.safe_load(Path(config_file).read_text()) or {}
    for part in dotted.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


class _StatusLine:
    """One line on stderr, rewritten about twice a second."""

    def __init__(self, quiet: bool):
        self.quiet = quiet
        self.last = None

    def __call__(self, s: dict) -> None:
        if self.quiet:
            return
        fps = s["frames"] / s["elapsed_s"] if s["elapsed_s"] > 0 else 0.0
        click.echo(f"\r{s['elapsed_s']:6.1f} s  {fps:5.1f} frames/s  processed {s['processed']}  dropped "
                   f"{s['dropped']}  lost rows {s['lost_rows']}  IMU {s['imu_samples']}  {s['tracking']:<12}",
                   nl=False, err=True)
        self.last = s

    def close(self) -> None:
        if not self.quiet and self.last is not None:
            click.echo("", err=True)
