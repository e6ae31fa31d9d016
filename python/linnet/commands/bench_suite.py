"""``linnet bench suite``: simulated replays of real EuRoC motions x scenes, each run by every system, evaluated with
the same APE code, printed as one markdown table (and written as markdown, JSON and a plot with ``--report``).

Replays are rendered once with the ``--realism`` preset (default ``hard``) and cached under ``--cache`` (default
~/.cache/linnet/sim/<trajectory>_<scene>_<hash of the arguments and the trajectory file's contents>). A system is
``linnet`` (the built-in: ``linnet run {dataset} --out {out} --quiet``) or ``NAME=CMD``, a shell command template with
``{dataset}`` (the EuRoC folder holding mav0/), ``{out}`` (an empty folder for the run) and ``{tum}`` (= {out}/
trajectory.tum, where the command must write its TUM trajectory); write literal braces as ``{{`` and ``}}``. If the
command also writes ``{out}/summary.json`` with Linnet's keys (initialisation_time_s, reinitialisations), those are
reported. Jobs run on Ray when it is installed (see linnet.suite), serially otherwise.

With ``--samples N`` the built-in linnet runs N times per replay, KLT's stop (points.klt_epsilon) at its default x
(1 + d), d = 0, -1 %, +1 %, -2 %, ...: a change no one would notice that still moves a single replay's APE by up to
2x, so that a comparison of two configurations can rest on each replay's mean and spread rather than on one run. A
command template takes part when it holds ``{klt_epsilon}`` (run once otherwise). A second table then gives, per
sequence, scene and system, the runs' APE mean, standard deviation, min and max and the mean real-time factor.
Linnet's odometry (``{out}/odometry.tum``, before loop correction) is evaluated too, and the last lines give each
system's mean over the replays of its per-replay means.

``--reference`` replaces the sequences, scenes and realism by the nine replays the README's Results are measured on:
five ``hard`` ones (V1_02, V2_01, V2_02 room; MH_01, MH_04 hall), the low-texture V1_02, V2_01, V2_02 with blur and
exposure changes, and V1_01 room with the real EuRoC IMU of the shared micro snippet, blur and exposure changes.
"""
from __future__ import annotations

import os
from pathlib import Path

import click

from linnet.commands.params import OUTPUT_DIR, OUTPUT_FILE
from linnet.evaluation import InputError as EvalInputError, write_json_file
from linnet.sim.realism import REALISM_LEVELS, REALISM_PRESETS
from linnet.suite import (SAMPLE_KEY, ReplaySpec, RunSpec, Suite, driver_thread_env, make_executor, markdown_table,
                          means_text, plot_rows, sample_summary, sample_values, summary_table, system_means,
                          template_field)

DEFAULT_SEQUENCES = ("V1_02_medium", "MH_01_easy", "V2_01_easy")

#: The real EuRoC IMU log that the reference set's real-IMU replay carries, relative to the shared data folder.
REFERENCE_REAL_IMU = Path("euroc") / "V1_01_easy_micro" / "mav0" / "imu0" / "data.csv"
#: The reference replays (README, Results): sequence, scene, settings label. "hard" is the realism preset of that
#: name; "blur" the easy one with blur and exposure changes; "real IMU" that with the real IMU log above.
REFERENCE_REPLAYS = (
    ("V1_02_medium", "room", "hard"), ("V2_01_easy", "room", "hard"), ("V2_02_medium", "room", "hard"),
    ("MH_01_easy", "hall", "hard"), ("MH_04_difficult", "hall", "hard"),
    ("V1_01_easy_vicon2gt", "room", "real IMU"),
    ("V1_02_medium", "lowtex", "blur"), ("V2_01_easy", "lowtex", "blur"), ("V2_02_medium", "lowtex", "blur"),
)


def reference_settings(label: str, real_imu: Path) -> tuple:
    """simulate()'s keyword arguments (sorted pairs) of a reference replay's settings label."""
    if label == "hard":
        return tuple(sorted(REALISM_PRESETS["hard"].items()))
    settings = dict(REALISM_PRESETS["easy"], blur=True, exposure_changes=True)
    if label == "real IMU":
        if not real_imu.is_file():
            raise click.UsageError(f"--reference: the real-IMU replay needs {real_imu} (the shared data folder, "
                                   "or $LINNET_SHARED_DATA)")
        settings["real_imu"] = str(real_imu)
    elif label != "blur":
        raise ValueError(f"unknown reference settings '{label}'")
    return tuple(sorted(settings.items()))


def shared_groundtruth_dir() -> Path:
    root = os.environ.get("LINNET_SHARED_DATA")
    if root:
        return Path(root) / "euroc_groundtruth"
    return Path(__file__).resolve().parents[3].parent / "shared" / "data" / "euroc_groundtruth"


def resolve_sequence(spec: str, gt_dir: Path) -> tuple[str, Path]:
    """A file path, or a sequence name looked up in gt_dir (the 17-column csv if present, else the TUM file)."""
    p = Path(spec)
    if p.is_file():
        return p.stem, p
    for cand in (gt_dir / f"{spec}.csv", gt_dir / f"{spec}.txt"):
        if cand.is_file():
            return spec, cand
    raise click.UsageError(f"sequence '{spec}': no file of that name and no {spec}.csv / {spec}.txt in {gt_dir}")


def default_scene(name: str) -> str:
    """Machine-hall motions go through the hall, Vicon-room motions through the room."""
    return "hall" if name.upper().startswith("MH") else "room"


def parse_systems(specs) -> list[tuple[str, str | None]]:
    systems = []
    for spec in specs:
        for item in ([spec] if "=" in spec else spec.split(",")):
            item = item.strip()
            if not item:
                continue
            if item == "linnet":
                systems.append(("linnet", None))
            elif "=" in item:
                name, cmd = item.split("=", 1)
                if not name.strip() or not cmd.strip():
                    raise click.UsageError(f"--systems: '{item}' is not NAME=CMD")
                systems.append((name.strip(), cmd.strip()))
            else:
                raise click.UsageError(f"--systems: unknown system '{item}' (use linnet or NAME=CMD)")
    return systems or [("linnet", None)]


def default_sample_base() -> float:
    """SAMPLE_KEY's default value in the built-in configuration."""
    from linnet import _linnet
    from linnet.api import config_value

    return float(config_value(_linnet.Config(), SAMPLE_KEY))


def replay_specs(sequences: str, scenes: str, duration, start, seed, realism, reference: bool) -> list:
    """The suite's replays, in table order: the reference set, or each sequence through each scene."""
    from linnet.sim.scene import SCENES

    gt_dir = shared_groundtruth_dir()
    if reference:
        real_imu = gt_dir.parent / REFERENCE_REAL_IMU
        replays = []
        for sequence, scene, label in REFERENCE_REPLAYS:
            name, gt_file = resolve_sequence(sequence, gt_dir)
            replays.append(ReplaySpec(name, str(gt_file), scene, seed, start, duration,
                                      reference_settings(label, real_imu), label))
        return replays
    seqs = [resolve_sequence(s.strip(), gt_dir) for s in sequences.split(",") if s.strip()]
    scene_list = [s.strip() for s in scenes.split(",") if s.strip()]
    for s in scene_list:
        if s != "auto" and s not in SCENES:
            raise click.UsageError(f"--scenes: unknown scene '{s}' (known: auto, {', '.join(SCENES)})")
    settings = tuple(sorted(REALISM_PRESETS[realism].items()))
    replays = []
    for name, gt_file in seqs:
        for scene in ([default_scene(name)] if scene_list == ["auto"] else scene_list):
            if scene == "auto":
                scene = default_scene(name)
            replay = ReplaySpec(name, str(gt_file), scene, seed, start, duration, settings)
            if replay not in replays:
                replays.append(replay)
    return replays


def build_suite(sequences: str, scenes: str, systems, duration, start, seed, realism, cache: Path,
                runs: Path, timeout: float, samples: int = 1, reference: bool = False) -> Suite:
    thread_env = driver_thread_env()
    values = sample_values(samples, default_sample_base())
    suite = Suite(cache=str(cache))
    suite.replays = replay_specs(sequences, scenes, duration, start, seed, realism, reference)
    for replay in suite.replays:
        name, scene = replay.name, replay.scene
        for sys_name, cmd in parse_systems(systems):
            folder = runs / f"{name}_{scene}" / sys_name
            sampled = cmd is None or "{" + template_field(SAMPLE_KEY) + "}" in cmd
            if samples == 1 or not sampled:
                run_settings = ((SAMPLE_KEY, values[0]),) if cmd is not None and sampled else ()
                suite.runs.append(RunSpec(replay, sys_name, cmd, str(folder), timeout, thread_env, 0,
                                          run_settings))
                continue
            for k, v in enumerate(values):
                suite.runs.append(RunSpec(replay, sys_name, cmd, str(folder / f"sample{k}"), timeout, thread_env,
                                          k, ((SAMPLE_KEY, v),)))
    return suite


@click.command("suite")
@click.option("--sequences", default=",".join(DEFAULT_SEQUENCES), show_default=True,
              help="Comma-separated EuRoC ground-truth names (looked up in ../shared/data/euroc_groundtruth or "
                   "$LINNET_SHARED_DATA) or trajectory files.")
@click.option("--scenes", default="auto", show_default=True,
              help="Comma-separated scenes (room, hall, lowtex, mixed); auto = hall for MH_*, room otherwise.")
@click.option("--systems", multiple=True, default=("linnet",), show_default=True,
              help="linnet and/or NAME=CMD (CMD with {dataset}, {out}, {tum}); repeat or comma-separate.")
@click.option("--realism", type=click.Choice(REALISM_LEVELS), default="hard", show_default=True,
              help="Simulator preset of the replays (see linnet simulate --help).")
@click.option("--duration", type=float, default=None, help="Seconds of each sequence (default: all of it).")
@click.option("--start", type=float, default=0.0, show_default=True, help="Seconds skipped into each sequence.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--cache", type=OUTPUT_DIR,
              default=Path.home() / ".cache" / "linnet" / "sim", show_default=True,
              help="Replay cache folder (on a cluster: a folder every node sees).")
@click.option("--runs", type=OUTPUT_DIR, default=Path("runs") / "suite",
              show_default=True, help="Where the systems' outputs go (on a cluster: a folder every node sees).")
@click.option("--executor", type=click.Choice(["auto", "serial", "ray"]), default="auto", show_default=True,
              help="auto: a local Ray instance on this machine's cores when Ray is installed, else serial.")
@click.option("--ray-address", default=None, metavar="ADDRESS",
              help="Run the jobs on an existing Ray cluster (e.g. 10.0.0.5:6379, or 'auto').")
@click.option("--timeout", type=float, default=3600.0, show_default=True, help="Seconds per system run.")
@click.option("--samples", type=click.IntRange(min=1), default=1, show_default=True,
              help="Runs of the built-in linnet per replay, KLT's stop (points.klt_epsilon) varied by 1 %, 2 %, ...: "
                   "each replay's APE mean and spread (a command template takes part with {klt_epsilon}).")
@click.option("--reference", is_flag=True,
              help="The nine replays of the README's Results (five hard; three low-texture and one with the real "
                   "EuRoC IMU, with blur and exposure changes) instead of --sequences, --scenes and --realism.")
@click.option("--json", "json_out", type=OUTPUT_FILE, help="Write the rows as JSON.")
@click.option("--report", "report_dir", type=OUTPUT_DIR, default=None,
              help="Write suite.md, suite.json and suite.png (APE and real-time factor per sequence, scene, system).")
def COMMAND(sequences, scenes, systems, realism, duration, start, seed, cache, runs, executor, ray_address, timeout,
            samples, reference, json_out, report_dir):
    """Replay EuRoC motions through simulated scenes and run each system: APE, real-time factor, failures, odometry."""
    import time

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    suite = build_suite(sequences, scenes, systems, duration, start, seed, realism, cache, runs, timeout, samples,
                        reference)
    for folder in (cache, runs, report_dir):
        if folder is not None:
            try:
                Path(folder).mkdir(parents=True, exist_ok=True)
            except OSError as e:
                raise click.ClickException(f"cannot create {folder}: {e.strerror}") from None
    echo = lambda m: click.echo(m, err=True)  # noqa: E731
    try:
        runner = make_executor(executor, ray_address, echo)
    except RuntimeError as e:
        raise click.ClickException(str(e)) from None
    total = len(suite.replays) + len(suite.runs)
    echo(f"[suite] {len(suite.replays)} replays ({'reference set' if reference else realism}), {len(suite.runs)} runs, "
         f"executor {runner.name}")
    t0 = time.perf_counter()
    with Progress(TextColumn("[bold]suite[/]"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  TextColumn("{task.description}"), transient=True) as bar:
        task = bar.add_task("", total=total)

        def progress(label):
            bar.update(task, advance=1, description=f"done: {label}")
            echo(f"[suite] done: {label}")

        try:
            rows = runner.run(suite, progress)
        except Exception as e:  # noqa: BLE001 - a bad trajectory file is a user error, also inside a Ray task
            from linnet.sim.trajectory import InputError

            cause = getattr(e, "cause", e)
            if isinstance(cause, InputError):
                raise click.ClickException(str(cause)) from None
            raise
    wall = time.perf_counter() - t0
    table = markdown_table(rows)
    summary = sample_summary(rows)
    if any(g["runs"] > 1 for g in summary):
        table += "\n\n" + summary_table(summary)
    means = system_means(summary)
    if len(summary) > len(means):  # more than one replay per system
        table += "\n\n" + means_text(means)
    click.echo(table)
    echo(f"[suite] {total} jobs in {wall:.1f} s wall ({runner.name})")
    try:
        if json_out:
            write_json_file(json_out, rows)
        if report_dir:
            report = {"realism": "reference" if reference else realism, "executor": runner.name, "wall_s": wall,
                      "rows": rows, "summary": summary, "means": means}
            write_json_file(report_dir / "suite.json", report)
    except EvalInputError as e:
        raise click.ClickException(str(e)) from None
    if report_dir:
        (report_dir / "suite.md").write_text(table + "\n")
        plot_rows(rows, report_dir / "suite.png")
        echo(f"[suite] wrote {report_dir}/suite.md, suite.json, suite.png")
