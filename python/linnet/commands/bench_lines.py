"""`linnet bench lines DATASET [--json FILE]`: per-stage median / p95 ms of the line front-end, counts, track lengths.

Times are measured inside the C++ tracker (steady clock around each stage; plus the thread's CPU time for the left
part and the whole frame, which other processes' load does not inflate); image loading is not included.
Pin to one core for the issue's figures: `taskset -c 1 linnet bench lines DATASET`.
"""
from __future__ import annotations

import json
from pathlib import Path

import click

from linnet.commands.params import OUTPUT_FILE

STAGES = ("detect_ms", "merge_ms", "describe_ms", "temporal_ms", "stereo_ms", "left_ms", "total_ms", "cpu_left_ms",
          "cpu_total_ms")


def bench(dataset, frames=None, options=None, mono=False, repeat=1):
    """Runs the tracker over the frames `repeat` times (fresh tracker each time); returns the result dict."""
    import numpy as np

    from linnet import lines

    data = lines.EurocStereo(dataset)
    start, stop = lines.parse_frames(frames, len(data))
    images = list(data.frames(start, stop))  # decode once: the loop times only the tracker
    # The gyroscope's rotation between frames (as the pipeline hands the tracker), when the dataset has imu0.
    rotations = [None] + [data.gyro_prediction(images[k - 1][0], images[k][0]) for k in range(1, len(images))]
    series = {s: [] for s in STAGES}
    counts = {"lines": [], "stereo_matched": [], "stereo_guided": [], "tracked": [], "new_lines": [],
              "detected_left": [], "detected_right": []}
    final_length, age, right_detected, left_detected, left_predicted = {}, [], [], [], []
    tracker = None
    for rep in range(repeat):
        tracker = lines.make_tracker(data, options, mono=mono)
        for k, (t_ns, left, right) in enumerate(images):
            if k > 0:
                R = rotations[k]
                if R is not None:
                    tracker.set_rotation_prediction(R)
            obs = tracker.track(t_ns, left, None if mono else right)
            tm = tracker.last_timings()
            for s in STAGES:
                series[s].append(tm[s])
            if rep == 0:
                counts["lines"].append(len(obs["id"]))
                for c in ("stereo_matched", "stereo_guided", "tracked", "new_lines"):
                    counts[c].append(tm[c])
                right_detected.append(bool(tm["right_detected"]))
                left_detected.append(bool(tm["left_detected"]))
                # Frames without an image's detection would count as 0 detected segments.
                if tm["left_detected"]:
                    counts["detected_left"].append(tm["detected_left"])
                else:
                    left_predicted.append(tm["left_predicted"])
                if tm["right_detected"]:
                    counts["detected_right"].append(tm["detected_right"])
                for i, n in zip(obs["id"], obs["track_length"]):
                    final_length[int(i)] = int(n)
                age.extend(int(n) for n in obs["track_length"])
    table = lines.percentile_table(series)
    return {
        "dataset": str(dataset), "frames": len(images), "repeat": repeat, "mono": mono,
        "options": tracker.options() if tracker is not None else {},
        "stages_ms": table,
        "counts_median": {k: float(np.median(v)) if v else 0.0 for k, v in counts.items()},
        "stereo_guided_mean": float(np.mean(counts["stereo_guided"])) if counts["stereo_guided"] else 0.0,
        "right_detected_fraction": float(np.mean(right_detected)) if right_detected else 0.0,
        "left_detected_fraction": float(np.mean(left_detected)) if left_detected else 0.0,
        "left_predicted_mean": float(np.mean(left_predicted)) if left_predicted else 0.0,
        "track_length": {
            "ids": len(final_length),
            "median_per_id": float(np.median(list(final_length.values()))) if final_length else 0.0,
            "mean_per_id": float(np.mean(list(final_length.values()))) if final_length else 0.0,
            "median_of_delivered_lines": float(np.median(age)) if age else 0.0,
        },
    }


def _default_trajectory() -> Path:
    import os

    root = Path(os.environ.get("LINNET_SHARED_DATA", Path(__file__).resolve().parents[3].parent / "shared" / "data"))
    return root / "euroc_groundtruth" / "V1_02_medium.txt"


@click.command("lines")
@click.argument("dataset", required=False, type=click.Path(exists=True, file_okay=False, path_type=Path))
@click.option("--json", "json_out", type=OUTPUT_FILE, help="Write the results as JSON.")
@click.option("--frames", default=None, help="Frame range A:B (Python slice).")
@click.option("--detector", type=click.Choice(["ed", "edlines", "fld", "lsd"]), default=None, help="Line detector.")
@click.option("--set", "settings", multiple=True, metavar="KEY=VALUE",
              help="Override a line front-end option (config section 'lines'), e.g. detection.min_length_px=30.")
@click.option("--repeat", type=int, default=1, show_default=True, help="Passes over the frames (timings pooled).")
@click.option("--mono", is_flag=True, help="Ignore cam1.")
@click.option("--sim", "sim_scene", default=None,
              help="Instead of DATASET: score against the simulator's true lines on this scene (e.g. lowtex, room).")
@click.option("--trajectory", type=click.Path(exists=True, dir_okay=False, path_type=Path), default=None,
              help="With --sim: the replayed trajectory (default: shared data's V1_02_medium ground truth).")
@click.option("--duration", type=float, default=30.0, show_default=True, help="With --sim: seconds replayed.")
def COMMAND(dataset, json_out, frames, detector, settings, repeat, mono, sim_scene, trajectory, duration):
    """Benchmark the line front-end on DATASET: per-stage median / p95 ms, counts and track lengths.
    With --sim SCENE: detection recall, temporal / stereo precision and track length against ground truth."""
    from linnet import _linnet, lines

    try:
        opts = lines.tracker_options(detector, settings)
    except ValueError as e:
        raise click.BadParameter(str(e), param_hint="--set") from e
    if sim_scene is not None:
        traj = trajectory or _default_trajectory()
        if not Path(traj).is_file():
            raise click.BadParameter(f"{traj}: not found", param_hint="--trajectory")
        res = lines.score_sim(str(traj), sim_scene, duration=duration, options=opts)
        click.echo(f"simulated {sim_scene} on {Path(traj).name}, {res['frames']} frames ({duration:g} s)")
        click.echo(f"detection recall {res['detection_recall']:.3f} of {res['gt_segments_considered']} visible "
                   f"segments > 40 px (unoccluded, contrast >= {res['min_contrast']:g}); "
                   f"{res['detection_recall_unoccluded']:.3f} of all {res['gt_segments_unoccluded']} unoccluded")
        click.echo(f"temporal precision {res['temporal_precision']:.4f} ({res['temporal_judged']} judged), stereo "
                   f"precision {res['stereo_precision']:.4f} ({res['stereo_judged']} judged)")
        tc = res["track_consistency"]
        click.echo(f"track consistency ({tc['tracks_scored']} tracks seen in >= 5 frames, each against the 3D line "
                   f"fitted to its sightings at the true poses): median {tc['median_px']:.2f} px, p90 "
                   f"{tc['p90_px']:.2f} px, {100 * tc['share_above_px']:.2f} % of sightings above {tc['bad_px']:g} px, "
                   f"in {100 * tc['tracks_with_bad_sighting']:.1f} % of the tracks")
        click.echo(f"median track length {res['median_track_length_per_id']:.0f} per id, "
                   f"{res['median_track_length_delivered']:.0f} for the delivered lines; "
                   f"{res['median_lines_per_frame']:.0f} lines / frame, {res['median_stereo_per_frame']:.0f} stereo")
        if json_out:
            json_out.parent.mkdir(parents=True, exist_ok=True)
            json_out.write_text(json.dumps(res, indent=2) + "\n", encoding="utf-8")
        return
    if dataset is None:
        raise click.UsageError("give DATASET or --sim SCENE")

    if repeat < 1:
        raise click.BadParameter("must be >= 1", param_hint="--repeat")
    try:
        res = bench(dataset, frames, opts, mono, repeat)
    except (lines.DatasetError, _linnet.ConfigError) as e:
        raise click.ClickException(str(e)) from e
    except ValueError as e:
        raise click.BadParameter(str(e), param_hint="--frames") from e
    click.echo(f"line front-end on {dataset} ({res['frames']} frames x {repeat}, detector "
               f"{res['options'].get('detection.detector')}, {'mono' if mono else 'stereo'})")
    click.echo("| stage | median ms | p95 ms | max ms |")
    click.echo("|---|---|---|---|")
    for name, s in res["stages_ms"].items():
        click.echo(f"| {name[:-3]} | {s['median']:.2f} | {s['p95']:.2f} | {s['max']:.2f} |")
    c = res["counts_median"]
    tl = res["track_length"]
    click.echo(f"median per frame: {c['lines']:.0f} lines, {c['stereo_matched']:.0f} stereo "
               f"({res['stereo_guided_mean']:.1f} guided on average), {c['tracked']:.0f} "
               f"tracked, {c['new_lines']:.0f} new; detected {c['detected_left']:.0f} left / "
               f"{c['detected_right']:.0f} right (on the {100 * res['left_detected_fraction']:.0f} / "
               f"{100 * res['right_detected_fraction']:.0f} % of frames with a left / right detection; "
               f"{res['left_predicted_mean']:.1f} left lines predicted on the others)")
    click.echo(f"track length: {tl['ids']} ids, median {tl['median_per_id']:.0f} (mean {tl['mean_per_id']:.1f}) "
               f"frames per id; median {tl['median_of_delivered_lines']:.0f} for the delivered lines")
    if json_out:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(res, indent=2) + "\n", encoding="utf-8")
