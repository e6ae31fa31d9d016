"""`linnet sensor emulate | record`: the stereo-IMU sensor module's emulator, and recording its stream as a EuRoC
folder (docs/sensor_protocol.md)."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR, OUTPUT_FILE, POSITIVE_SECONDS, key_values
from linnet.commands.progress import ProgressBar


def sensor_config(config_file, overrides, base=None, native_size_of=None):
    """`base` (default: the defaults) + config file + --set; with `native_size_of` = (W, H), the sensor section's image
    size unless --set gives it."""
    import linnet
    from linnet.api import apply_settings

    cfg = apply_settings(base if base is not None else linnet.Config(), config_file, list(overrides))
    given = {item.partition("=")[0].strip() for item in overrides}
    if native_size_of is not None:
        for key, value in zip(("sensor.width", "sensor.height"), native_size_of):
            if key not in given:
                cfg.set(key, int(value))
    return cfg


def _image_size(dataset: Path):
    """(W, H) of the dataset's first cam0 image; ClickException naming the file when it cannot be read."""
    import cv2

    from linnet.fileio import InputError, read_text_file

    csv = dataset / "mav0" / "cam0" / "data.csv"
    if not csv.is_file():
        csv = dataset / "cam0" / "data.csv"
    try:
        rows = [line for line in read_text_file(csv, "a EuRoC cam0/data.csv", name_if_missing=True).splitlines()
                if line.strip() and not line.startswith("#")]
    except InputError as e:
        raise click.ClickException(str(e)) from None
    fields = rows[0].split(",") if rows else []
    if len(fields) < 2:
        raise click.ClickException(f"{csv}: no image listed (expected 'timestamp,filename' rows)")
    image = cv2.imread(str(csv.parent / "data" / fields[1].strip()), cv2.IMREAD_GRAYSCALE)
    if image is None:
        raise click.ClickException(f"{csv.parent / 'data' / fields[1].strip()}: cannot read the first image")
    return image.shape[1], image.shape[0]


@click.group("sensor")
def COMMAND():
    """The stereo-IMU sensor module: an emulator streaming a EuRoC folder over UDP, and a recorder."""


@COMMAND.command("emulate")
@click.argument("dataset", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--port", type=click.IntRange(1, 65535), required=True, help="UDP port of the driver.")
@click.option("--host", default="127.0.0.1", show_default=True, help="IPv4 address of the driver.")
@click.option("--rate", type=POSITIVE_SECONDS, default=1.0, show_default=True, help="Speed, x real time.")
@click.option("--drop-prob", type=click.FloatRange(0.0, 1.0, max_open=True), default=0.0, show_default=True,
              help="Drop each packet with this probability (reported exactly in --json).")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed of the drops.")
@click.option("--duration", type=POSITIVE_SECONDS, default=None, help="Stream only this many seconds of images.")
@click.option("--loops", type=click.IntRange(min=1), default=1, show_default=True,
              help="Stream the images this many times (time stamps continue): a long stream from a short folder.")
@click.option("--native-size", is_flag=True,
              help="Stream at the dataset's image size instead of the module's W x H (config sensor.width/height; "
                   "smaller images are padded, larger cropped).")
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Config file (its sensor section: W, H, IMU ranges).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", callback=key_values,
              help="Override one config key (repeatable).")
@click.option("--json", "json_file", type=OUTPUT_FILE, help="Write what was sent and dropped as JSON.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def emulate(dataset, port, host, rate, drop_prob, seed, duration, loops, native_size, config_file, overrides, json_file,
            quiet):
    """Stream DATASET (a EuRoC folder) over UDP as the sensor module would: image rows, IMU packets and frame packets,
    paced in real time x --rate, with the IMU from 1 s before the first image."""
    import linnet
    from linnet.evaluation import write_json_file

    try:
        cfg = sensor_config(config_file, overrides, native_size_of=_image_size(dataset) if native_size else None)
        with ProgressBar("emulate", quiet) as progress:
            report = linnet._linnet.emulate_dataset(str(dataset), cfg, host=host, port=port, rate=rate,
                                                    drop_prob=drop_prob, seed=seed,
                                                    duration_s=-1.0 if duration is None else duration, loops=loops,
                                                    progress=progress)
    except linnet.Error as e:
        raise click.ClickException(str(e)) from None
    dropped_rows = report["rows_dropped_cam0"] + report["rows_dropped_cam1"]
    click.echo(f"sent {report['packets_sent']} packets ({report['bytes_sent'] / 1e6:.1f} MB), {report['frames']} "
               f"frames, {report['imu_samples_sent']} IMU samples in {report['wall_s']:.2f} s (data "
               f"{report['data_s']:.2f} s); dropped {report['packets_dropped']} packets ({dropped_rows} rows, "
               f"{report['frame_packets_dropped']} frame packets, {report['imu_dropped']} IMU samples); worst lateness "
               f"{report['late_s'] * 1e3:.1f} ms")
    if json_file is not None:
        write_json_file(json_file, report)


@COMMAND.command("record")
@click.option("--udp", "port", type=click.IntRange(0, 65535), required=True, help="UDP port to listen on.")
@click.option("--host", default="127.0.0.1", show_default=True, help="IPv4 address to listen on (0.0.0.0: all).")
@click.option("--out", type=OUTPUT_DIR, required=True, help="EuRoC folder to write (mav0/cam0, cam1, imu0).")
@click.option("--duration", type=POSITIVE_SECONDS, default=None, help="Stop after this many seconds of stream.")
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Config file (its sensor section: W, H, IMU ranges).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", callback=key_values,
              help="Override one config key (repeatable).")
def record(port, host, out, duration, config_file, overrides):
    """Write the module's stream as a EuRoC folder (replay it with `linnet run`), until --duration, the stream going
    idle (sensor.idle_timeout_s), or Ctrl-C. The calibration is not in the stream: add sensor.yaml files or use
    `linnet run --calib`."""
    import linnet

    try:
        cfg = sensor_config(config_file, overrides)
        result = linnet._linnet.run_live(cfg, host=host, port=port, duration_s=-1.0 if duration is None else duration,
                                         record_dir=str(out), run_system=False,
                                         on_ready=lambda p: click.echo(f"recording udp://{host}:{p} -> {out}",
                                                                       err=True))
    except linnet.Error as e:
        raise click.ClickException(str(e)) from None
    c = result["counters"]
    click.echo(f"recorded {result['recorded_frames']} frames and {result['recorded_imu']} IMU samples ({result['end_reason']});"
               f" lost rows {c['lost_rows_cam0']} / {c['lost_rows_cam1']}, dropped frames {c['frames_dropped']}, lost "
               f"IMU samples {c['lost_imu_samples']}")


@COMMAND.command("listen")
@click.option("--udp", "port", type=click.IntRange(0, 65535), required=True, help="UDP port to listen on.")
@click.option("--host", default="127.0.0.1", show_default=True, help="IPv4 address to listen on (0.0.0.0: all).")
@click.option("--duration", type=POSITIVE_SECONDS, default=None, help="Stop after this many seconds of stream.")
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Config file (its sensor section: W, H, IMU ranges, driver policies).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", callback=key_values,
              help="Override one config key (repeatable).")
@click.option("--json", "json_file", type=OUTPUT_FILE, help="Write the driver counters as JSON.")
def listen(port, host, duration, config_file, overrides, json_file):
    """Receive the module's stream with the driver only (no SLAM, nothing written) and print its counters: packets,
    lost rows and IMU samples, incomplete frames, ring-buffer high-water mark, receive / parse thread CPU time."""
    import linnet
    from linnet.evaluation import write_json_file

    try:
        cfg = sensor_config(config_file, overrides)
        result = linnet._linnet.run_live(cfg, host=host, port=port, duration_s=-1.0 if duration is None else duration,
                                         run_system=False,
                                         on_ready=lambda p: click.echo(f"listening on udp://{host}:{p}", err=True))
    except linnet.Error as e:
        raise click.ClickException(str(e)) from None
    c = result["counters"]
    click.echo(" ".join(f"{k}={v:.3f}" if isinstance(v, float) else f"{k}={v}" for k, v in c.items())
               + f" end={result['end_reason']}")
    if json_file is not None:
        write_json_file(json_file, dict(c, end_reason=result["end_reason"]))
