"""`linnet lines DATASET --out DIR [--frames A:B]`: debug view of the line front-end (PNGs + per-frame csv)."""
from __future__ import annotations

from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR

CSV_COLUMNS = ("frame", "t_ns", "lines", "stereo_matched", "tracked", "new_lines", "detected_left", "detected_right",
               "detect_ms", "merge_ms", "describe_ms", "temporal_ms", "stereo_ms", "left_ms", "total_ms", "cpu_left_ms",
               "cpu_total_ms")


def _options(detector, max_lines, settings=()):
    from linnet.lines import tracker_options

    try:
        opts = tracker_options(detector, settings)
    except ValueError as e:
        raise click.BadParameter(str(e), param_hint="--set") from e
    if max_lines:
        opts["max_lines"] = max_lines
    return opts


@click.command("lines")
@click.argument("dataset", type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--out", "out_dir", required=True, type=OUTPUT_DIR,
              help="Output folder for frame_NNNNNN.png and lines.csv.")
@click.option("--frames", default=None, help="Frame range A:B (Python slice, e.g. 0:50 or -20:).")
@click.option("--detector", type=click.Choice(["ed", "edlines", "fld", "lsd"]), default=None,
              help="Line detector (default: the configured one, ed).")
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
              help="Override a line front-end option (config section 'lines'), e.g. detection.min_length_px=30.")
@click.option("--max-lines", type=int, default=None, help="Lines delivered per frame.")
@click.option("--mono", is_flag=True, help="Ignore cam1.")
@click.option("--no-png", is_flag=True, help="Only write lines.csv.")
def COMMAND(dataset, out_dir, frames, detector, settings, max_lines, mono, no_png):
    """Track lines through DATASET (a EuRoC folder); write PNGs coloured by id (left | right) and lines.csv."""
    import cv2

    from linnet import lines

    try:
        data = lines.EurocStereo(dataset)
        start, stop = lines.parse_frames(frames, len(data))
        data.load_imu()
    except lines.DatasetError as e:
        raise click.ClickException(str(e)) from e
    except ValueError as e:
        raise click.BadParameter(str(e), param_hint="--frames") from e
    from linnet import _linnet

    try:
        tracker = lines.make_tracker(data, _options(detector, max_lines, settings), mono=mono)
    except _linnet.ConfigError as e:
        raise click.ClickException(str(e)) from e
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    prev_t = None
    for k, (t_ns, left, right) in enumerate(data.frames(start, stop), start=start):
        R = data.gyro_prediction(prev_t, t_ns) if prev_t is not None else None
        if R is not None:  # the gyroscope's rotation since the previous frame, as the pipeline gives it
            tracker.set_rotation_prediction(R)
        prev_t = t_ns
        obs = tracker.track(t_ns, left, None if mono else right)
        tm = tracker.last_timings()
        rows.append((k, t_ns, len(obs["id"]), tm["stereo_matched"], tm["tracked"], tm["new_lines"],
                     tm["detected_left"], tm["detected_right"], tm["detect_ms"], tm["merge_ms"], tm["describe_ms"],
                     tm["temporal_ms"], tm["stereo_ms"], tm["left_ms"], tm["total_ms"], tm["cpu_left_ms"],
                     tm["cpu_total_ms"]))
        if not no_png:
            label = (f"frame {k}  lines {len(obs['id'])}  stereo {tm['stereo_matched']}  tracked {tm['tracked']}  "
                     f"{tm['total_ms']:.1f} ms")
            cv2.imwrite(str(out_dir / f"frame_{k:06d}.png"), lines.draw_tracks(left, None if mono else right, obs, label))
    with open(out_dir / "lines.csv", "w", encoding="utf-8") as f:
        f.write("#" + ",".join(CSV_COLUMNS) + "\n")
        for r in rows:
            f.write(",".join(f"{v:.3f}" if isinstance(v, float) else str(v) for v in r) + "\n")
    click.echo(f"{len(rows)} frames -> {out_dir} (lines.csv{'' if no_png else ' + PNGs'})")
