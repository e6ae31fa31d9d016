"""`linnet run INPUT`: run a EuRoC-format folder or a ROS bag and write the trajectory, timings, map and a summary.

Exit codes (as every command): 0 the run tracked; 1 bad input data (named in the message); 2 usage error; 3 the run
went through but failed to track (never initialised, or lost most frames): the outputs are written and the reasons
printed and stored in summary.json ("status", "problems").
"""
from __future__ import annotations

import json
from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR, SECONDS, key_values
from linnet.commands.progress import ProgressBar

#: Exit code of a run that went through but did not track (see the module docstring).
EXIT_TRACKING_FAILED = 3


@click.command("run")
@click.argument("source", metavar="INPUT", type=click.Path(exists=True, path_type=Path))
@click.option("--config", "config_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="YAML file overriding the defaults (see `linnet config`).")
@click.option("--calib", "calib_files", multiple=True, type=click.Path(exists=True, path_type=Path),
              metavar="FILE",
              help="Kalibr calibration instead of the dataset's sensor.yaml files: a camchain (camchain-imucam.yaml; "
                   "pinhole radtan or equidistant) and optionally an imu.yaml (repeat --calib). For a ROS bag, a "
                   "EuRoC folder is accepted too (its sensor.yaml files are used).")
@click.option("--out", type=OUTPUT_DIR, default=None, help="Output folder (default: runs/<input name>).")
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE", callback=key_values,
              help="Override one config key, e.g. --set pipeline.use_lines=false (repeatable).")
@click.option("--max-frames", type=click.IntRange(min=-1), default=-1, show_default=True,
              help="Stop after N frames (-1: all).")
@click.option("--start", type=SECONDS, default=0.0, show_default=True,
              help="Skip the first S seconds of images.")
@click.option("--realtime", type=click.FloatRange(min=0.0, min_open=True), is_flag=False, flag_value=1.0,
              default=None, metavar="[SPEED]",
              help="Pace the input by its time stamps (SPEED x real time, default 1) in real-time mode: frames the "
                   "system cannot take in time are dropped and counted, as live.")
@click.option("--cam0-topic", default="/cam0/image_raw", show_default=True, help="ROS bag: left camera topic.")
@click.option("--cam1-topic", default="/cam1/image_raw", show_default=True,
              help="ROS bag: right camera topic ('' for monocular).")
@click.option("--imu-topic", default="/imu0", show_default=True, help="ROS bag: IMU topic.")
@click.option("--quiet", is_flag=True, help="No progress bar.")
def COMMAND(source, config_file, calib_files, out, overrides, max_frames, start, realtime, cam0_topic, cam1_topic,
            imu_topic, quiet):
    """Run Linnet on INPUT: a EuRoC folder (holding mav0/), or a ROS1 .bag / ROS2 bag folder (with --calib). Writes
    trajectory.tum, trajectory.csv, timing.csv, map.ply, map_lines.csv and summary.json to --out; prints the APE
    when the dataset has ground truth. Exit code 3 when the run did not track (reasons printed)."""
    import linnet
    from linnet import bag_run, bags
    from linnet.api import summarize, write_outputs

    out = out or Path("runs") / source.resolve().name
    is_bag = bag_run.is_bag(source)
    try:
        if is_bag:
            topics = bags.BagTopics(cam0=cam0_topic, cam1=cam1_topic or None, imu=imu_topic)
            cfg = _bag_config(source, topics, calib_files, config_file, overrides)
            run = _run_bag(linnet, source, topics, cfg, max_frames, start, realtime, quiet)
            dataset = None
        else:
            cfg = _folder_config(source, calib_files, config_file, overrides)
            run = _run_folder(linnet, source, cfg, calib_files, max_frames, start, realtime, quiet)
            dataset = source
    except (linnet.Error, bags.BagError) as e:
        raise click.ClickException(str(e)) from None
    for warning in run.warnings:
        click.echo(f"linnet run: warning: {warning}", err=True)
    summary = summarize(run, dataset)
    summary["input"] = str(source)
    write_outputs(run, summary, out)
    _print_summary(summary, out)
    if summary["status"] != "ok":
        for problem in summary["problems"]:
            click.echo(f"linnet run: tracking failed: {problem}", err=True)
        raise click.exceptions.Exit(EXIT_TRACKING_FAILED)


def _calibration(calib_files):
    """The --calib files -> linnet.api.Calibration (camchain / imu.yaml told apart by their keys)."""
    from linnet.api import Calibration
    from linnet.fileio import read_text_file

    import yaml

    calib = Calibration()
    for path in calib_files:
        if path.is_dir():
            raise click.BadParameter(f"{path}: a folder (only a ROS bag run takes a EuRoC folder)", param_hint="--calib")
        try:
            doc = yaml.safe_load(read_text_file(path, "a Kalibr YAML file"))
        except yaml.YAMLError as e:
            raise click.BadParameter(f"{path}: invalid YAML ({e})", param_hint="--calib") from None
        if isinstance(doc, dict) and "cam0" in doc:
            calib.camchain = str(path)
        elif isinstance(doc, dict) and ("imu0" in doc or "accelerometer_noise_density" in doc):
            calib.imu_yaml = str(path)
        else:
            raise click.BadParameter(f"{path}: neither a Kalibr camchain (cam0: ...) nor a Kalibr imu.yaml "
                                     "(accelerometer_noise_density, ...)", param_hint="--calib")
    return calib


def _folder_config(dataset, calib_files, config_file, overrides):
    from linnet.api import load_config

    return load_config(dataset, config_file, list(overrides), calib=_calibration(calib_files))


def calibration_config(calib_files, rate_hz):
    """The config of a --calib given for a source without calibration files (a bag, the sensor module): a EuRoC folder
    alone (its sensor.yaml files), or Kalibr files; `rate_hz()` gives the camera rate a camchain does not hold."""
    import linnet

    folders = [p for p in calib_files if p.is_dir()]
    if folders:
        if len(calib_files) > 1:
            raise click.BadParameter("a EuRoC folder is the whole calibration: give it alone", param_hint="--calib")
        return linnet.Config.for_euroc(str(folders[0]))
    calib = _calibration(calib_files)
    if not calib.camchain:
        raise click.BadParameter("no Kalibr camchain among the --calib files", param_hint="--calib")
    return linnet.Config.for_kalibr(calib.camchain, calib.imu_yaml, rate_hz())


def _bag_config(bag, topics, calib_files, config_file, overrides):
    from linnet import bag_run
    from linnet.api import apply_settings

    if not calib_files:
        raise click.UsageError("a ROS bag holds no calibration: give --calib camchain.yaml [--calib imu.yaml] "
                               "(Kalibr), or --calib EUROC_FOLDER")
    cfg = apply_settings(calibration_config(calib_files, lambda: bag_run.frame_rate(bag, topics)), config_file,
                         list(overrides))
    if cfg.stereo != topics.stereo:
        raise click.UsageError(f"the calibration has {'two cameras' if cfg.stereo else 'one camera'} but "
                               f"{'a cam1 topic was given' if topics.stereo else '--cam1-topic is empty'}")
    return cfg


def _run_folder(linnet, dataset, cfg, calib_files, max_frames, start, realtime, quiet):
    calib = _calibration(calib_files)
    with ProgressBar("linnet run", quiet) as progress:
        return linnet._linnet.run_euroc(str(dataset), cfg, max_frames, start, progress, camchain=calib.camchain,
                                        imu_yaml=calib.imu_yaml, realtime_speed=realtime or 0.0)


def _run_bag(linnet, bag, topics, cfg, max_frames, start, realtime, quiet):
    from linnet import bag_run

    with ProgressBar("linnet run", quiet) as progress:
        return bag_run.run_bag(bag, topics, cfg, max_frames=max_frames, start_s=start, realtime_speed=realtime or 0.0,
                            progress=progress)


def _print_summary(summary: dict, out: Path) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"linnet run: {summary['input']}", show_header=False)
    rows = [
        ("frames (processed / with pose)",
         f"{summary['frames']} ({summary['processed_frames']} / {summary['frames_with_pose']})"),
        ("initialisation time", f"{summary['initialisation_time_s']:.2f} s"
         if summary["initialisation_time_s"] >= 0 else "never initialised"),
        ("re-initialisations", str(summary["reinitialisations"])),
        ("wall time", f"{summary['wall_time_s']:.2f} s"),
        ("real-time factor (wall / CPU)",
         f"{summary['real_time_factor']:.3f} / {summary['cpu_real_time_factor']:.3f} "
         f"(images decoded in {summary['image_load_cpu_s']:.1f} s CPU)"),
    ]
    if summary["dropped_frames"]:
        rows.append(("dropped frames", str(summary["dropped_frames"])))
    if "ape" in summary:
        ape = summary["ape"]
        rows.append(("APE RMSE (SE3, position)", f"{ape['rmse_m']:.4f} m over {ape['pairs']} poses"))
        rows.append(("path length (estimate / gt)",
                     f"{summary['path_length_m']:.3f} m / {summary['gt_path_length_m']:.3f} m"))
    if "time_offset_ms" in summary:
        rows.append(("camera-to-IMU time offset (online)", f"{summary['time_offset_ms']:.2f} ms"))
    if "extrinsics_correction" in summary:
        c = summary["extrinsics_correction"]
        rows.append(("extrinsics correction (online)",
                     f"{c['rotation_deg']:.3f} deg, {1e3 * c['translation_m']:.2f} mm"))
    if "stereo_correction" in summary:
        c = summary["stereo_correction"]
        rows.append(("cam1 correction (online)", f"{c['rotation_deg']:.4f} deg, {1e3 * c['translation_m']:.3f} mm"))
    if summary.get("map_line_candidates"):
        rows.append(("line map", f"{summary['map_lines']} lines published of {summary['map_line_candidates']} "
                                 f"(estimator.lines.map); {summary['reidentified_lines']} new tracks "
                                 "re-identified as window lines"))
    if "line_adjustment" in summary:
        a = summary["line_adjustment"]
        solved = "solved" if a["solved"] else "not solved"
        rows.append(("line map adjustment", f"{a['joined']} of {a['lines']} lines joined into {a['groups']}, "
                                            f"pose graph {solved}, CPU {a['cpu_s']:.2f} s"))
    if "loop_closure" in summary:
        lc = summary["loop_closure"]
        rows.append(("loop closure", f"{lc['loops']} loops, largest correction {lc['largest_correction_m']:.3f} m; "
                                     f"{lc['keyframes']} keyframes, {lc['graph_nodes']} graph nodes, "
                                     f"{lc['described']} described ({lc['place_mb']:.1f} MB)"))
    rows.append(("status", summary["status"]))
    for k, v in rows:
        table.add_row(k, v)
    Console().print(table)
    click.echo(f"outputs in {out}/ (summary.json: {json.dumps(summary.get('ape', {}).get('rmse_m'))})")
