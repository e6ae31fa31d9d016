"""``linnet convert BAG --out DIR``: a ROS1 .bag or ROS2 bag (sqlite3 / MCAP) -> a EuRoC folder for ``linnet run``."""
from __future__ import annotations

from pathlib import Path

import click


@click.command("convert")
@click.argument("bag", type=click.Path(path_type=Path))
@click.option("--out", "out_dir", required=True, type=click.Path(path_type=Path),
              help="EuRoC folder to write (mav0/...); must not exist or be empty.")
@click.option("--cam0-topic", default="/cam0/image_raw", show_default=True,
              help="Left (or only) camera: sensor_msgs/Image or CompressedImage.")
@click.option("--cam1-topic", default=None,
              help="Right camera topic [default: /cam1/image_raw]; paired with cam0 by identical header stamp.")
@click.option("--mono", is_flag=True, help="Monocular: read cam0 only (excludes --cam1-topic).")
@click.option("--imu-topic", default="/imu0", show_default=True, help="sensor_msgs/Imu topic.")
@click.option("--calib-from", type=click.Path(exists=True, file_okay=False, path_type=Path), default=None,
              metavar="EUROC_DIR", help="Copy mav0/*/sensor.yaml (and body.yaml) from this EuRoC folder.")
@click.option("--lookahead", type=click.FloatRange(min=0.0, min_open=True), default=0.5, show_default=True,
              help="Window for re-ordering messages by header stamp and pairing stereo images, seconds.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def COMMAND(bag, out_dir, cam0_topic, cam1_topic, mono, imu_topic, calib_from, lookahead, quiet):
    """Convert the ROS bag BAG (a ROS1 .bag file, or a ROS2 bag folder / .db3 / .mcap) into a EuRoC folder:
    cam0 (and cam1) PNGs with data.csv, imu0/data.csv. Time stamps are the message header stamps. Exit code 1
    on an unreadable bag, missing topics or a non-empty output folder."""
    from linnet import bags

    if mono and cam1_topic is not None:
        raise click.UsageError("--mono and --cam1-topic exclude each other")
    topics = bags.BagTopics(cam0=cam0_topic, cam1=None if mono else (cam1_topic or "/cam1/image_raw"),
                            imu=imu_topic)
    try:
        stats = _convert(bags, bag, out_dir, topics, calib_from, lookahead, quiet)
    except bags.BagError as e:
        raise click.ClickException(" ".join(str(e).split())) from None
    click.echo(f"{bag} -> {out_dir}: {stats.summary()}")
    for note in stats.notes:
        click.echo(f"note: {note}")


def _convert(bags, bag, out_dir, topics, calib_from, lookahead, quiet):
    if quiet:
        return bags.convert_bag(bag, out_dir, topics, calib_from=calib_from, lookahead_s=lookahead)
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("[bold]linnet convert[/bold]"), BarColumn(), MofNCompleteColumn(),
                  TextColumn("messages"), TimeRemainingColumn(), transient=True) as bar:
        task = bar.add_task("messages", total=None)

        def progress(done, total):
            if done == 1 or done % 50 == 0 or done == total:
                bar.update(task, completed=done, total=total)

        return bags.convert_bag(bag, out_dir, topics, progress, calib_from=calib_from, lookahead_s=lookahead)
