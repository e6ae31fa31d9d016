"""The benchmark suite's jobs and executors (``linnet bench suite``).

A suite is a list of replays (a EuRoC motion through a scene, rendered once and cached) and, for each replay, one run
per system. Render jobs and run jobs are plain functions of plain arguments, so that the same code runs

  * serially in this process (``SerialExecutor``), or
  * on Ray (``RayExecutor``; https://docs.ray.io): a local instance on this machine's cores, or an existing cluster by
    address. Each job asks for one CPU; a run job waits for its replay's render job (Ray passes the render's result).
    The replay cache and the run folders must then be on a folder every node sees (``--cache``, ``--runs``).

Rows are collected in the suite's own order whatever the completion order, so a serial and a Ray run of the same
suite give the same rows (timings aside). Ray is an optional dependency (``pip install linnet[cluster]``).
"""
from __future__ import annotations

import hashlib
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

SIM_VERSION = "sim-4"  # bump when the simulator's output changes, to invalidate caches
#: Row keys that are timings (they differ between two runs of the same suite); every other key is reproducible.
TIMING_KEYS = ("real_time_factor", "wall_s", "render_s")
#: Environment variables that set libraries' thread counts. Ray sets some of them in its workers (OMP_NUM_THREADS=1);
#: a system run inherits them, and a different thread count can change the floating-point summation order. Run jobs
#: therefore get the values the suite was started with, whichever executor runs them.
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "TBB_NUM_THREADS")


@dataclass(frozen=True)
class ReplaySpec:
    name: str                 # sequence name
    gt_file: str              # trajectory file
    scene: str
    seed: int
    start: float
    duration: Optional[float]
    settings: tuple           # sorted (key, value) pairs of simulate()'s realism keyword arguments
    label: str = ""           # what the settings are called in tables (e.g. "hard"); not part of the cache key

    def key(self) -> str:
        h = hashlib.sha256()
        h.update(Path(self.gt_file).read_bytes())
        h.update(json.dumps([SIM_VERSION, self.scene, self.seed, self.start, self.duration,
                             list(self.settings)]).encode())
        return h.hexdigest()[:16]

    def folder(self, cache: Path) -> Path:
        return Path(cache) / f"{Path(self.gt_file).stem}_{self.scene}_{self.key()}"


@dataclass(frozen=True)
class RunSpec:
    replay: ReplaySpec
    system: str
    command: Optional[str]    # None: the built-in linnet
    out: str
    timeout_s: float
    thread_env: tuple = ()    # (name, value or None) of THREAD_ENV as the suite was started
    sample: int = 0           # index among the runs of this system on this replay (--samples)
    settings: tuple = ()      # (key, value) config settings of this sample: "--set key=value" for the built-in
                              # linnet, "{key}" with the key's last part (e.g. {klt_epsilon}) in a command template


@dataclass
class Suite:
    replays: list = field(default_factory=list)   # ReplaySpec, in table order
    runs: list = field(default_factory=list)      # RunSpec, in table order
    cache: str = ""


# ------------------------------------------------------------------------------------------------------------ jobs


def render_job(spec: ReplaySpec, cache: str) -> dict:
    """Render the replay into the cache unless it is there; returns {"dataset": folder, "summary": ..., "rendered"}.
    Writes into a temporary folder first, so that a concurrent or interrupted render never leaves half a replay."""
    from linnet.sim import simulate

    folder = spec.folder(Path(cache))
    done = folder / "replay.json"
    if done.is_file():
        return {"dataset": str(folder), "summary": json.loads(done.read_text()), "rendered": False}
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = folder.with_name(f"{folder.name}.tmp-{uuid.uuid4().hex[:8]}")
    try:
        summary = simulate(spec.gt_file, spec.scene, tmp, seed=spec.seed, start=spec.start, duration=spec.duration,
                           **dict(spec.settings))
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)  # no half replay left behind
        raise
    summary["out_dir"] = str(folder)
    (tmp / "replay.json").write_text(json.dumps(summary, indent=2, sort_keys=True))
    if folder.exists():  # another job finished the same replay meanwhile: keep theirs
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        tmp.rename(folder)
    return {"dataset": str(folder), "summary": json.loads(done.read_text()), "rendered": True}


def driver_thread_env() -> tuple:
    """THREAD_ENV as set in this process (None where unset), for RunSpec.thread_env."""
    return tuple((name, os.environ.get(name)) for name in THREAD_ENV)


def _run_system(cmd: Optional[str], dataset: Path, out: Path, timeout: float, thread_env: tuple = (),
                settings: tuple = ()) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    tum = out / "trajectory.tum"
    for stale in (tum, out / ODOMETRY_FILE):
        if stale.exists():
            stale.unlink()
    if cmd is None:
        argv = [sys.executable, "-m", "linnet.cli", "run", str(dataset), "--out", str(out), "--quiet"]
        for key, value in settings:
            argv += ["--set", f"{key}={value}"]
    else:
        fields = {template_field(key): shlex.quote(str(value)) for key, value in settings}
        text = cmd.format(dataset=shlex.quote(str(dataset)), out=shlex.quote(str(out)), tum=shlex.quote(str(tum)),
                          **fields)
        argv = ["/bin/sh", "-c", text]
    env = dict(os.environ)
    for name, value in thread_env:
        if value is None:
            env.pop(name, None)
        else:
            env[name] = value
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, env=env)
        rc, err = proc.returncode, proc.stderr.strip().splitlines()[-1:] if proc.stderr.strip() else []
    except subprocess.TimeoutExpired:
        rc, err = -1, [f"timed out after {timeout:g} s"]
    wall = time.perf_counter() - t0
    (out / "suite_stderr.txt").write_text("\n".join(err) + "\n")
    result = {"returncode": rc, "wall_s": wall, "error": err[0] if (rc != 0 and err) else None}
    summary_file = out / "summary.json"
    if summary_file.is_file():
        try:
            result["summary"] = json.loads(summary_file.read_text())
        except json.JSONDecodeError:
            pass
    return result


def _evaluate(tum: Path, gt: Path):
    from linnet import evaluation

    if not tum.is_file():
        return None, "no trajectory written"
    try:
        return float(evaluation.ape(str(tum), str(gt), align="se3", t_max_diff=0.01).rmse), None
    except Exception as e:  # noqa: BLE001 - report any evaluation failure in the table
        return None, str(e).splitlines()[0][:80]


#: A run's odometry (the estimate before loop correction), evaluated too when the system writes it (Linnet does).
ODOMETRY_FILE = "odometry.tum"


def run_job(spec: RunSpec, replay: dict) -> dict:
    """Run one system on a rendered replay and evaluate it: one table row."""
    dataset = Path(replay["dataset"])
    sim = replay["summary"]
    out = Path(spec.out)
    res = _run_system(spec.command, dataset, out, spec.timeout_s, spec.thread_env, spec.settings)
    gt = dataset / "mav0" / "state_groundtruth_estimate0" / "data.csv"
    ape, eval_err = _evaluate(out / "trajectory.tum", gt)
    odometry, _ = _evaluate(out / ODOMETRY_FILE, gt)  # None when the system wrote none
    summ = res.get("summary", {})
    seq_dur = sim["duration_s"]
    return {
        "sequence": spec.replay.name, "scene": spec.replay.scene, "system": spec.system, "sample": spec.sample,
        "settings": dict(spec.settings), "ape_rmse_m": ape, "ape_odometry_m": odometry,
        "real_time_factor": float(summ.get("real_time_factor", res["wall_s"] / max(seq_dur, 1e-9))),
        "init_time_s": summ.get("initialisation_time_s"),
        "failures": summ.get("reinitialisations", 0 if res["returncode"] == 0 else None),
        "error": res["error"] or (eval_err if ape is None else None),
        "returncode": res["returncode"], "wall_s": res["wall_s"], "frames": sim["frames"],
        "duration_s": seq_dur, "dataset": str(dataset), "out": str(out),
        "realism": dict(spec.replay.settings), "replay_label": spec.replay.label,
    }


#: The config key that --samples varies: KLT's stop. A change of it that no one would notice (1 %) takes a run down
#: another floating-point path, and a single replay's APE can then move by up to 2x (README, Results): one run is one
#: sample of a spread.
SAMPLE_KEY = "points.klt_epsilon"


def template_field(key: str) -> str:
    """The command-template field of a config key: its last part (points.klt_epsilon -> klt_epsilon)."""
    return key.rsplit(".", 1)[-1]


def sample_values(n: int, base: float) -> list:
    """n values of SAMPLE_KEY around its default `base`: base x (1 + d), d = 0, -1 %, +1 %, -2 %, +2 %, ..."""
    if n < 1:
        raise ValueError(f"samples must be >= 1, got {n}")
    out = []
    for k in range(n):
        d = 0.01 * ((k + 1) // 2) * (-1 if k % 2 else 1)
        out.append(float(f"{base * (1.0 + d):.6g}"))
    return out


# ------------------------------------------------------------------------------------------------------- executors


class SerialExecutor:
    name = "serial"

    def run(self, suite: Suite, progress: Callable[[str], None]) -> list:
        renders = {}
        rows = []
        for spec in suite.replays:
            renders[spec] = render_job(spec, suite.cache)
            progress(f"replay {spec.name}/{spec.scene}")
        for run in suite.runs:
            rows.append(run_job(run, renders[run.replay]))
            progress(f"{run.system} on {run.replay.name}/{run.replay.scene}")
        return rows


class RayExecutor:
    """Jobs as Ray tasks of one CPU each. address None: a local instance (this machine's cores)."""
    name = "ray"

    def __init__(self, address: Optional[str] = None, num_cpus: Optional[int] = None):
        import ray  # noqa: F401 - fail early with ImportError when the extra is missing

        self.address, self.num_cpus = address, num_cpus

    def run(self, suite: Suite, progress: Callable[[str], None]) -> list:
        import ray

        started_here = not ray.is_initialized()
        if started_here:
            kwargs = {"include_dashboard": False, "log_to_driver": False, "configure_logging": False}
            if self.address:
                ray.init(address=self.address, **kwargs)
            else:
                ray.init(num_cpus=self.num_cpus, **kwargs)
        try:
            remote_render = ray.remote(num_cpus=1, max_retries=0)(render_job)
            remote_run = ray.remote(num_cpus=1, max_retries=0)(run_job)
            render_refs = {spec: remote_render.remote(spec, suite.cache) for spec in suite.replays}
            labels = {}
            for spec, ref in render_refs.items():
                labels[ref] = f"replay {spec.name}/{spec.scene}"
            run_refs = [remote_run.remote(run, render_refs[run.replay]) for run in suite.runs]
            for run, ref in zip(suite.runs, run_refs):
                labels[ref] = f"{run.system} on {run.replay.name}/{run.replay.scene}"
            pending = list(labels)
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                progress(labels[ready[0]])
            return ray.get(run_refs)
        finally:
            if started_here:
                ray.shutdown()


def make_executor(mode: str, address: Optional[str] = None, echo: Callable[[str], None] = print):
    """mode: "auto" (Ray when installed, else serial), "serial" or "ray"; an address implies Ray."""
    if mode == "serial" and not address:
        return SerialExecutor()
    try:
        return RayExecutor(address)
    except ImportError:
        if mode == "ray" or address:
            raise RuntimeError("Ray is not installed: pip install 'linnet[cluster]' (or run with --executor serial)")
        echo("[suite] Ray is not installed (pip install 'linnet[cluster]'): running the jobs serially")
        return SerialExecutor()


# ---------------------------------------------------------------------------------------------------------- output


def markdown_table(rows: list) -> str:
    head = ("| sequence | scene | system | APE RMSE [m] | real-time factor | init [s] | failures | odometry APE [m] |\n"
            "|---|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        ape = f"{r['ape_rmse_m']:.3f}" if r["ape_rmse_m"] is not None else "—"
        odometry = f"{r['ape_odometry_m']:.3f}" if r.get("ape_odometry_m") is not None else "—"
        init = f"{r['init_time_s']:.2f}" if r["init_time_s"] is not None else "—"
        fail = r["failures"] if r["failures"] is not None else "—"
        if r["error"]:
            fail = f"{fail} ({r['error']})"
        system = r["system"] + "".join(f" ({k}={v})" for k, v in (r.get("settings") or {}).items())
        lines.append(f"| {r['sequence']} | {scene_label(r)} | {system} | {ape} | {r['real_time_factor']:.2f} | "
                     f"{init} | {fail} | {odometry} |")
    return "\n".join(lines)


def scene_label(row: dict) -> str:
    """The scene, with the replay's settings label when it has one (``room (hard)``)."""
    label = row.get("replay_label")
    return f"{row['scene']} ({label})" if label else row["scene"]


def sample_summary(rows: list) -> list:
    """One dict per sequence / scene / system (first-seen order) over its samples: count, APE mean, standard deviation
    (of the samples, n - 1; None for fewer than 2), min, max (over the runs with an APE), mean real-time factor and
    the failures summed (None if any run's count is unknown)."""
    import statistics

    groups: dict = {}
    for r in rows:
        groups.setdefault((r["sequence"], scene_label(r), r["system"]), []).append(r)
    out = []
    for (sequence, scene, system), rs in groups.items():
        apes = [r["ape_rmse_m"] for r in rs if r["ape_rmse_m"] is not None]
        # over the same runs as ape_mean_m, and only when each of them wrote its odometry
        odometry = [r.get("ape_odometry_m") for r in rs if r["ape_rmse_m"] is not None]
        fails = [r["failures"] for r in rs]
        out.append({
            "sequence": sequence, "scene": scene, "system": system, "runs": len(rs), "evaluated": len(apes),
            "ape_odometry_mean_m": statistics.fmean(odometry) if odometry and None not in odometry else None,
            "ape_mean_m": statistics.fmean(apes) if apes else None,
            "ape_sd_m": statistics.stdev(apes) if len(apes) >= 2 else None,
            "ape_min_m": min(apes) if apes else None, "ape_max_m": max(apes) if apes else None,
            "real_time_factor_mean": statistics.fmean(r["real_time_factor"] for r in rs),
            "failures": None if any(f is None for f in fails) else sum(fails),
        })
    return out


def summary_table(summary: list) -> str:
    """sample_summary() as markdown."""
    def m(x):
        return f"{x:.4f}" if x is not None else "—"

    lines = ["| sequence | scene | system | runs | APE mean [m] | sd [m] | min [m] | max [m] | real-time factor | "
             "failures | odometry APE mean [m] |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for g in summary:
        runs = f"{g['evaluated']} of {g['runs']}" if g["evaluated"] != g["runs"] else str(g["runs"])
        fails = g["failures"] if g["failures"] is not None else "—"
        lines.append(f"| {g['sequence']} | {g['scene']} | {g['system']} | {runs} | {m(g['ape_mean_m'])} | "
                     f"{m(g['ape_sd_m'])} | {m(g['ape_min_m'])} | {m(g['ape_max_m'])} | "
                     f"{g['real_time_factor_mean']:.3f} | {fails} | {m(g.get('ape_odometry_mean_m'))} |")
    return "\n".join(lines)


def system_means(summary: list) -> list:
    """Per system (first-seen order), the mean over its replays of sample_summary()'s per-replay APE means (and of
    the odometry's): the one figure that compares two configurations over a whole suite. None where a replay has no
    mean."""
    import statistics

    systems: dict = {}
    for g in summary:
        systems.setdefault(g["system"], []).append(g)
    out = []
    for system, gs in systems.items():
        def mean_of(key):
            values = [g.get(key) for g in gs]
            return statistics.fmean(values) if all(v is not None for v in values) else None

        out.append({"system": system, "replays": len(gs), "ape_mean_m": mean_of("ape_mean_m"),
                    "ape_odometry_mean_m": mean_of("ape_odometry_mean_m")})
    return out


def means_text(means: list) -> str:
    """system_means() as one line per system."""
    def m(x):
        return f"{x:.5f} m" if x is not None else "—"

    return "\n".join(f"{g['system']}: mean over {g['replays']} replays, APE {m(g['ape_mean_m'])}, odometry "
                     f"{m(g['ape_odometry_mean_m'])}" for g in means)


def reproducible(row: dict) -> dict:
    """The row without its timings: what a serial and a Ray run of the same suite share bit for bit."""
    return {k: v for k, v in row.items() if k not in TIMING_KEYS}


def plot_rows(rows: list, path) -> Path:
    """Two panels, APE RMSE and real-time factor, one bar per system for each sequence / scene."""
    import numpy as np

    from linnet.plots import PlotOptions, _figure, _save

    groups = list(dict.fromkeys(f"{r['sequence']}\n{r['scene']}" for r in rows))
    systems = list(dict.fromkeys(r["system"] for r in rows))
    fig = _figure(PlotOptions(), height_in=6.0)
    axes = fig.subplots(2, 1, sharex=True)
    width = 0.8 / max(1, len(systems))
    x = np.arange(len(groups))
    for j, system in enumerate(systems):
        ape = [next((r["ape_rmse_m"] for r in rows if r["system"] == system and
                     f"{r['sequence']}\n{r['scene']}" == g), None) for g in groups]
        rtf = [next((r["real_time_factor"] for r in rows if r["system"] == system and
                     f"{r['sequence']}\n{r['scene']}" == g), None) for g in groups]
        offs = x + (j - (len(systems) - 1) / 2) * width
        axes[0].bar(offs, [np.nan if v is None else v for v in ape], width, label=system, color=f"C{j}")
        axes[1].bar(offs, [np.nan if v is None else v for v in rtf], width, color=f"C{j}")
    axes[0].set_ylabel("APE RMSE [m]")
    axes[1].set_ylabel("real-time factor")
    axes[1].axhline(1.0, color="0.5", lw=0.6, ls="--")
    axes[1].set_xticks(x, groups, fontsize=8)
    axes[0].legend(fontsize=8)
    for ax in axes:
        ax.grid(True, axis="y", lw=0.3)
    return _save(fig, path)
