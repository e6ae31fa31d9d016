"""CLI of the simulator: `linnet simulate` and `linnet bench suite` (with a stand-in system)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from linnet.commands.bench_suite import markdown_table, parse_systems

LINNET = [sys.executable, "-m", "linnet.cli"]


def _run(*args, cwd=None):
    return subprocess.run(LINNET + list(args), capture_output=True, text=True, cwd=cwd, timeout=600)


def test_simulate_writes_a_dataset_and_its_summary(tmp_path):
    out = tmp_path / "seq"
    r = _run("simulate", "--trajectory", "builtin:loop", "--scene", "room", "--out", str(out), "--start", "5",
             "--duration", "1", "--seed", "4", "--json", str(tmp_path / "s.json"))
    assert r.returncode == 0, r.stderr
    assert "21 stereo frames" in r.stdout
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["frames"] == 21 and summary["fit"]["position_rms_m"] < 1e-4
    assert len(list((out / "mav0" / "cam1" / "data").glob("*.png"))) == 21
    assert (out / "mav0" / "imu0" / "data.csv").read_text().count("\n") == 1 + 201


@pytest.mark.parametrize("args, message, code", [
    (["--scene", "garden"], "garden", 2),
    (["--imu-noise", "loud"], "imu-noise", 2),
    (["--trajectory", "builtin:spiral"], "unknown built-in", 1),
    (["--trajectory", "/no/such/file.txt"], "no such file", 1),
    (["--duration", "0.1"], "duration", 1),
])
def test_simulate_bad_arguments_give_one_line_and_the_exit_code(tmp_path, args, message, code):
    """Usage errors (a bad option value click can judge) exit with 2, what the simulator cannot use with 1."""
    base = {"--trajectory": "builtin:loop", "--scene": "room", "--out": str(tmp_path / "x")}
    for k, v in zip(args[::2], args[1::2]):
        base[k] = v
    r = _run("simulate", *[x for kv in base.items() for x in kv])
    assert r.returncode == code, (r.stdout, r.stderr)
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("linnet") and message in lines[0], r.stderr


def test_parse_systems():
    assert parse_systems(("linnet",)) == [("linnet", None)]
    assert parse_systems(("linnet,linnet",)) == [("linnet", None), ("linnet", None)]
    assert parse_systems(("linnet", "other=cmd {dataset},x")) == [("linnet", None), ("other", "cmd {dataset},x")]
    with pytest.raises(Exception):
        parse_systems(("nonsense",))


def test_bench_suite_runs_a_system_template_on_a_cached_replay(tmp_path, short_loop_tum):
    # A 4 s trajectory file (TUM) and a stand-in "system" that writes the ground truth as its estimate, plus one
    # that fails: the table must show APE 0 for the first and the failure for the second.
    tum = short_loop_tum
    oracle = ("oracle=awk -F, '!/^#/ {{printf \"%.9f %s %s %s %s %s %s %s\\n\", $1/1e9, $2, $3, $4, $6, $7, $8, $5}}' "
              "{dataset}/mav0/state_groundtruth_estimate0/data.csv > {tum}")
    args = ["bench", "suite", "--sequences", str(tum), "--scenes", "lowtex", "--duration", "1.5", "--start", "2",
            "--systems", oracle, "--systems", "broken=exit 3", "--cache", str(tmp_path / "cache"),
            "--runs", str(tmp_path / "runs"), "--json", str(tmp_path / "rows.json"), "--executor", "serial",
            "--realism", "easy"]
    r = _run(*args)
    assert r.returncode == 0, r.stderr
    table = [line for line in r.stdout.splitlines() if line.startswith("|")]
    assert len(table) == 4 and "| short | lowtex | oracle | 0.000 |" in table[2], r.stdout
    assert "broken" in table[3] and "—" in table[3]
    rows = json.loads((tmp_path / "rows.json").read_text())
    assert rows[0]["ape_rmse_m"] < 1e-6 and rows[1]["ape_rmse_m"] is None and rows[1]["returncode"] == 3
    # Second run: the replay comes from the cache (no "simulating" message).
    r2 = _run(*args)
    assert r2.returncode == 0 and "simulating" not in r2.stderr


def test_markdown_table_formats_missing_values():
    text = markdown_table([{"sequence": "a", "scene": "room", "system": "x", "ape_rmse_m": None,
                            "real_time_factor": 0.5, "init_time_s": None, "failures": None, "error": "boom"}])
    assert "| a | room | x | — | 0.50 | — | — (boom) |" in text


def test_bench_suite_names_a_bad_trajectory_and_leaves_no_half_replay(tmp_path):
    bad = tmp_path / "bad.txt"
    bad.write_text("0 0 0\n")
    r = _run("bench", "suite", "--sequences", str(bad), "--scenes", "room", "--executor", "serial",
             "--cache", str(tmp_path / "cache"), "--runs", str(tmp_path / "runs"))
    assert r.returncode == 1 and "bad.txt" in r.stderr.splitlines()[-1], r.stderr
    assert not any((tmp_path / "cache").iterdir())
