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


def test_sample_values_step_the_klt_stop_by_one_percent_each_side():
    from linnet.suite import sample_values

    assert sample_values(1, 0.01) == [0.01]
    assert sample_values(5, 0.01) == [0.01, 0.0099, 0.0101, 0.0098, 0.0102]
    with pytest.raises(ValueError):
        sample_values(0, 0.01)


def test_sample_summary_gives_each_systems_mean_and_spread():
    from linnet.suite import sample_summary, summary_table

    def row(system, ape, failures=0):
        return {"sequence": "a", "scene": "room", "system": system, "ape_rmse_m": ape, "real_time_factor": 0.2,
                "failures": failures}

    summary = sample_summary([row("x", 0.01), row("y", 0.05), row("x", 0.02), row("x", None, None), row("x", 0.03)])
    assert [g["system"] for g in summary] == ["x", "y"]
    x, y = summary
    assert x["runs"] == 4 and x["evaluated"] == 3 and x["failures"] is None
    assert x["ape_mean_m"] == pytest.approx(0.02) and x["ape_sd_m"] == pytest.approx(0.01)
    assert (x["ape_min_m"], x["ape_max_m"]) == (0.01, 0.03)
    assert y["runs"] == 1 and y["ape_sd_m"] is None and y["failures"] == 0
    text = summary_table(summary)
    assert "| a | room | x | 3 of 4 | 0.0200 | 0.0100 | 0.0100 | 0.0300 | 0.200 | — |" in text
    assert "| a | room | y | 1 | 0.0500 | — | 0.0500 | 0.0500 | 0.200 | 0 |" in text


def test_build_suite_samples_the_built_in_system_and_templates_that_ask_for_it(tmp_path, short_loop_tum):
    from linnet.commands.bench_suite import build_suite

    suite = build_suite(str(short_loop_tum), "room", ("linnet", "t=run {klt_epsilon} {out}", "u=run {out}"), 1.0,
                        0.0, 0, "easy", tmp_path / "cache", tmp_path / "runs", 60.0, samples=3)
    by_system = {}
    for run in suite.runs:
        by_system.setdefault(run.system, []).append(run)
    assert [r.settings for r in by_system["linnet"]] == [(("points.klt_epsilon", v),) for v in (0.01, 0.0099, 0.0101)]
    assert [r.sample for r in by_system["t"]] == [0, 1, 2] and len({r.out for r in by_system["t"]}) == 3
    assert len(by_system["u"]) == 1 and by_system["u"][0].settings == ()
    single = build_suite(str(short_loop_tum), "room", ("linnet",), 1.0, 0.0, 0, "easy", tmp_path / "cache",
                         tmp_path / "runs", 60.0)
    assert len(single.runs) == 1 and single.runs[0].settings == ()


def test_bench_suite_samples_print_the_spread(tmp_path, short_loop_tum):
    # The stand-in system writes the ground truth and records the KLT stop it was given.
    oracle = ("oracle=echo {klt_epsilon} > {out}/eps.txt && awk -F, '!/^#/ {{printf \"%.9f %s %s %s %s %s %s %s\\n\", "
              "$1/1e9, $2, $3, $4, $6, $7, $8, $5}}' {dataset}/mav0/state_groundtruth_estimate0/data.csv > {tum}")
    r = _run("bench", "suite", "--sequences", str(short_loop_tum), "--scenes", "lowtex", "--duration", "1.5",
             "--start", "2", "--systems", oracle, "--samples", "2", "--cache", str(tmp_path / "cache"),
             "--runs", str(tmp_path / "runs"), "--json", str(tmp_path / "rows.json"), "--executor", "serial",
             "--realism", "easy")
    assert r.returncode == 0, r.stderr
    assert "| short | lowtex | oracle | 2 | 0.0000 | 0.0000 | 0.0000 | 0.0000 |" in r.stdout, r.stdout
    rows = json.loads((tmp_path / "rows.json").read_text())
    assert [row["sample"] for row in rows] == [0, 1]
    assert [(tmp_path / "runs" / "short_lowtex" / "oracle" / f"sample{k}" / "eps.txt").read_text().strip()
            for k in (0, 1)] == ["0.01", "0.0099"]
    bad = _run("bench", "suite", "--sequences", str(short_loop_tum), "--samples", "0", "--executor", "serial")
    assert bad.returncode == 2 and "samples" in bad.stderr


def test_build_suite_reference_set_is_the_readmes_nine_replays(tmp_path, shared_data):
    from linnet.commands.bench_suite import REFERENCE_REAL_IMU, build_suite
    from linnet.sim.realism import REALISM_PRESETS

    shared_data("euroc_groundtruth")
    real_imu = shared_data(str(REFERENCE_REAL_IMU))
    suite = build_suite("ignored", "ignored", ("linnet",), None, 0.0, 0, "easy", tmp_path / "cache",
                        tmp_path / "runs", 60.0, reference=True)
    replays = [(r.name, r.scene, r.label) for r in suite.replays]
    assert replays == [("V1_02_medium", "room", "hard"), ("V2_01_easy", "room", "hard"),
                       ("V2_02_medium", "room", "hard"), ("MH_01_easy", "hall", "hard"),
                       ("MH_04_difficult", "hall", "hard"), ("V1_01_easy_vicon2gt", "room", "real IMU"),
                       ("V1_02_medium", "lowtex", "blur"), ("V2_01_easy", "lowtex", "blur"),
                       ("V2_02_medium", "lowtex", "blur")]
    settings = [dict(r.settings) for r in suite.replays]
    assert all(s == REALISM_PRESETS["hard"] for s in settings[:5])
    blur = dict(REALISM_PRESETS["easy"], blur=True, exposure_changes=True)
    assert settings[6:] == [blur] * 3 and settings[5] == dict(blur, real_imu=str(real_imu))
    # One run each, in its own folder; a replay's label is not part of its cache key.
    assert len(suite.runs) == 9 and len({run.out for run in suite.runs}) == 9
    assert len({r.key() for r in suite.replays}) == 9


def test_bench_suite_evaluates_the_odometry_and_gives_each_systems_mean(tmp_path, short_loop_tum):
    # The stand-in writes the ground truth as its trajectory and as its odometry; a second one writes no odometry.
    gt_to_tum = ("awk -F, '!/^#/ {{printf \"%.9f %s %s %s %s %s %s %s\\n\", $1/1e9, $2, $3, $4, $6, $7, $8, $5}}' "
                 "{dataset}/mav0/state_groundtruth_estimate0/data.csv")
    both = f"both={gt_to_tum} > {{tum}} && cp {{tum}} {{out}}/odometry.tum"
    plain = f"plain={gt_to_tum} > {{tum}}"
    r = _run("bench", "suite", "--sequences", str(short_loop_tum), "--scenes", "lowtex,room", "--duration", "1.0",
             "--start", "2", "--systems", both, "--systems", plain, "--cache", str(tmp_path / "cache"),
             "--runs", str(tmp_path / "runs"), "--json", str(tmp_path / "rows.json"), "--executor", "serial",
             "--realism", "easy")
    assert r.returncode == 0, r.stderr
    rows = json.loads((tmp_path / "rows.json").read_text())
    assert [row["system"] for row in rows] == ["both", "plain", "both", "plain"]
    assert all(row["ape_odometry_m"] < 1e-6 for row in rows if row["system"] == "both")
    assert all(row["ape_odometry_m"] is None for row in rows if row["system"] == "plain")
    table = [line for line in r.stdout.splitlines() if line.startswith("|")]
    assert table[2].startswith("| short | lowtex | both | 0.000 |") and table[2].endswith("| 0.000 |"), r.stdout
    assert table[3].endswith("| — |")
    assert "both: mean over 2 replays, APE 0.00000 m, odometry 0.00000 m" in r.stdout, r.stdout
    assert "plain: mean over 2 replays, APE 0.00000 m, odometry —" in r.stdout


def test_system_means_average_the_per_replay_means():
    from linnet.suite import sample_summary, system_means

    def row(sequence, ape, odometry):
        return {"sequence": sequence, "scene": "room", "system": "x", "ape_rmse_m": ape, "ape_odometry_m": odometry,
                "real_time_factor": 0.2, "failures": 0}

    # Replay a: two samples (means 0.02 / 0.04), replay b: one (0.05 / 0.07); the mean of the means, not of the runs.
    summary = sample_summary([row("a", 0.01, 0.03), row("a", 0.03, 0.05), row("b", 0.05, 0.07)])
    assert summary[0]["ape_odometry_mean_m"] == pytest.approx(0.04)
    (means,) = system_means(summary)
    assert means["replays"] == 2
    assert means["ape_mean_m"] == pytest.approx(0.035) and means["ape_odometry_mean_m"] == pytest.approx(0.055)
    # A run without its odometry leaves that replay, and so the system, without an odometry mean.
    summary = sample_summary([row("a", 0.01, 0.03), row("a", 0.03, None), row("b", 0.05, 0.07)])
    assert summary[0]["ape_odometry_mean_m"] is None and system_means(summary)[0]["ape_odometry_mean_m"] is None
