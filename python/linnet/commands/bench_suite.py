"""``linnet bench suite``: simulated replays of real EuRoC motions x scenes, each run by every system, evaluated with
the same APE code, printed as one markdown table.

Replays are generated once and cached under ``--cache`` (default ~/.cache/linnet/sim/<hash of the arguments and the
trajectory file's contents>). A system is ``linnet`` (the built-in: ``linnet run {dataset} --out {out} --quiet``) or
``NAME=CMD``, a shell command template with ``{dataset}`` (the EuRoC folder holding mav0/), ``{out}`` (an empty folder
for the run) and ``{tum}`` (= {out}/trajectory.tum, where the command must write its TUM trajectory); write literal
braces as ``{{`` and ``}}``. If the command
also writes ``{out}/summary.json`` with Linnet's keys (initialisation_time_s, reinitialisations), those are reported.
"""
from __future__ import annotations

import hashlib
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

import click

SIM_VERSION = "sim-2"  # bump when the simulator's output changes, to invalidate caches
DEFAULT_SEQUENCES = ("V1_02_medium", "MH_01_easy", "V2_01_easy")


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


def cache_key(gt_file: Path, scene: str, seed: int, start: float, duration: float | None) -> str:
    h = hashlib.sha256()
    h.update(gt_file.read_bytes())
    h.update(json.dumps([SIM_VERSION, scene, seed, start, duration]).encode())
    return h.hexdigest()[:16]


def ensure_replay(gt_file: Path, scene: str, seed: int, start: float, duration: float | None, cache: Path,
                  echo) -> tuple[Path, dict]:
    from linnet.sim import simulate

    folder = cache / f"{gt_file.stem}_{scene}_{cache_key(gt_file, scene, seed, start, duration)}"
    done = folder / "replay.json"
    if done.is_file():
        return folder, json.loads(done.read_text())
    echo(f"[suite] simulating {gt_file.stem} in '{scene}' -> {folder}")
    summary = simulate(str(gt_file), scene, folder, seed=seed, start=start, duration=duration)
    done.write_text(json.dumps(summary, indent=2, sort_keys=True))
    return folder, summary


def run_system(name: str, cmd: str | None, dataset: Path, out: Path, timeout: float) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    tum = out / "trajectory.tum"
    if tum.exists():
        tum.unlink()
    if cmd is None:
        argv = [sys.executable, "-m", "linnet.cli", "run", str(dataset), "--out", str(out), "--quiet"]
    else:
        text = cmd.format(dataset=shlex.quote(str(dataset)), out=shlex.quote(str(out)), tum=shlex.quote(str(tum)))
        argv = ["/bin/sh", "-c", text]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, timeout=timeout)
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


def evaluate(tum: Path, gt: Path) -> tuple[float | None, str | None]:
    from linnet import evaluation

    if not tum.is_file():
        return None, "no trajectory written"
    try:
        return float(evaluation.ape(str(tum), str(gt), align="se3", t_max_diff=0.01).rmse), None
    except Exception as e:  # noqa: BLE001 - report any evaluation failure in the table
        return None, str(e).splitlines()[0][:80]


def markdown_table(rows: list[dict]) -> str:
    head = ("| sequence | scene | system | APE RMSE [m] | real-time factor | init [s] | failures |\n"
            "|---|---|---|---|---|---|---|")
    lines = [head]
    for r in rows:
        ape = f"{r['ape_rmse_m']:.3f}" if r["ape_rmse_m"] is not None else "—"
        init = f"{r['init_time_s']:.2f}" if r["init_time_s"] is not None else "—"
        fail = r["failures"] if r["failures"] is not None else "—"
        if r["error"]:
            fail = f"{fail} ({r['error']})"
        lines.append(f"| {r['sequence']} | {r['scene']} | {r['system']} | {ape} | {r['real_time_factor']:.2f} | "
                     f"{init} | {fail} |")
    return "\n".join(lines)


@click.command("suite")
@click.option("--sequences", default=",".join(DEFAULT_SEQUENCES), show_default=True,
              help="Comma-separated EuRoC ground-truth names (looked up in ../shared/data/euroc_groundtruth or "
                   "$LINNET_SHARED_DATA) or trajectory files.")
@click.option("--scenes", default="auto", show_default=True,
              help="Comma-separated scenes (room, hall, lowtex, mixed); auto = hall for MH_*, room otherwise.")
@click.option("--systems", multiple=True, default=("linnet",), show_default=True,
              help="linnet and/or NAME=CMD (CMD with {dataset}, {out}, {tum}); repeat or comma-separate.")
@click.option("--duration", type=float, default=None, help="Seconds of each sequence (default: all of it).")
@click.option("--start", type=float, default=0.0, show_default=True, help="Seconds skipped into each sequence.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--cache", type=click.Path(file_okay=False, path_type=Path),
              default=Path.home() / ".cache" / "linnet" / "sim", show_default=True, help="Replay cache folder.")
@click.option("--runs", type=click.Path(file_okay=False, path_type=Path), default=Path("runs") / "suite",
              show_default=True, help="Where the systems' outputs go.")
@click.option("--timeout", type=float, default=3600.0, show_default=True, help="Seconds per system run.")
@click.option("--json", "json_out", type=click.Path(dir_okay=False, path_type=Path), help="Write the rows as JSON.")
def COMMAND(sequences, scenes, systems, duration, start, seed, cache, runs, timeout, json_out):
    """Replay EuRoC motions through simulated scenes, run each system, print APE / real-time factor / init / failures."""
    from linnet.sim.scene import SCENES

    gt_dir = shared_groundtruth_dir()
    seqs = [resolve_sequence(s.strip(), gt_dir) for s in sequences.split(",") if s.strip()]
    scene_list = [s.strip() for s in scenes.split(",") if s.strip()]
    for s in scene_list:
        if s != "auto" and s not in SCENES:
            raise click.UsageError(f"--scenes: unknown scene '{s}' (known: auto, {', '.join(SCENES)})")
    system_list = parse_systems(systems)
    rows = []
    for name, gt_file in seqs:
        for scene in ([default_scene(name)] if scene_list == ["auto"] else scene_list):
            if scene == "auto":
                scene = default_scene(name)
            dataset, sim_summary = ensure_replay(gt_file, scene, seed, start, duration, cache,
                                                 lambda m: click.echo(m, err=True))
            gt = dataset / "mav0" / "state_groundtruth_estimate0" / "data.csv"
            for sys_name, cmd in system_list:
                click.echo(f"[suite] {sys_name} on {name}/{scene}", err=True)
                out = runs / f"{name}_{scene}" / sys_name
                res = run_system(sys_name, cmd, dataset, out, timeout)
                ape, eval_err = evaluate(out / "trajectory.tum", gt)
                summ = res.get("summary", {})
                seq_dur = sim_summary["duration_s"]
                rows.append({
                    "sequence": name, "scene": scene, "system": sys_name, "ape_rmse_m": ape,
                    "real_time_factor": float(summ.get("real_time_factor", res["wall_s"] / max(seq_dur, 1e-9))),
                    "init_time_s": summ.get("initialisation_time_s"),
                    "failures": summ.get("reinitialisations", 0 if res["returncode"] == 0 else None),
                    "error": res["error"] or (eval_err if ape is None else None),
                    "returncode": res["returncode"], "wall_s": res["wall_s"], "frames": sim_summary["frames"],
                    "duration_s": seq_dur, "dataset": str(dataset), "out": str(out),
                })
    click.echo(markdown_table(rows))
    if json_out:
        json_out.write_text(json.dumps(rows, indent=2) + "\n")
