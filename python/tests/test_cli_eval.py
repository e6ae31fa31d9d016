"""CLI tests of ``linnet eval``: help, the peer cross-check through the command, JSON and plots, one-line errors."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest
from click.testing import CliRunner

from linnet.cli import cli

CROSSCHECK = "eval_crosscheck/vinsmono_MH_01"


def run_linnet(*args):
    """The real entry point (linnet.cli:main) in a subprocess: exit code, stdout, stderr."""
    proc = subprocess.run([sys.executable, "-m", "linnet.cli", *map(str, args)], capture_output=True, text=True,
                          timeout=300)
    return proc.returncode, proc.stdout, proc.stderr


def write(path, text):
    path.write_text(text)
    return path


@pytest.fixture
def small_pair(tmp_path):
    """An L of 2 m + 2 m at 10 Hz (gt) and an estimate offset by 10 cm in z (no alignment: APE 0.1 m).

    (A straight line would make the SE3 alignment degenerate: a rotation about it is unobservable.)
    """
    gt_lines, est_lines = [], []
    for i in range(41):
        t = 100.0 + 0.1 * i
        x, y = (0.1 * i, 0.0) if i <= 20 else (2.0, 0.1 * (i - 20))
        gt_lines.append(f"{t:.9f} {x:.6f} {y:.6f} 0 0 0 0 1")
        est_lines.append(f"{t:.9f} {x:.6f} {y:.6f} 0.1 0 0 0 1")
    return write(tmp_path / "est.txt", "\n".join(est_lines) + "\n"), write(tmp_path / "gt.txt", "\n".join(gt_lines))


def test_help_lists_the_options():
    result = CliRunner().invoke(cli, ["eval", "--help"])
    assert result.exit_code == 0, result.output
    for option in ("--align", "--t-max-diff", "--plot", "--json", "--rpe-delta"):
        assert option in result.output
    assert "eval" in CliRunner().invoke(cli, ["--help"]).output


def test_crosscheck_through_the_cli(shared_data, tmp_path):
    folder = shared_data(CROSSCHECK)
    out = tmp_path / "res.json"
    result = CliRunner().invoke(cli, ["eval", str(folder / "vins_tum.txt"), str(folder / "ground_truth.tum"),
                                      "--t-max-diff", "0.1", "--align", "se3", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert "0.140305" in result.output and "771" in result.output
    report = json.loads(out.read_text())
    assert report["ape"]["rmse"] == pytest.approx(0.1403045640930528, abs=1e-5)
    assert report["ape"]["pairs"] == 771
    assert report["ape"]["align"] == "se3" and report["ape"]["pose_relation"] == "trans_part"
    assert report["rpe"]["pairs"] > 0 and report["rpe"]["delta"] == 1.0
    assert report["estimate_poses"] == 773
    assert any("identity orientations" in n for n in report["notes"])  # a position-only (Leica) ground truth
    result = CliRunner().invoke(cli, ["eval", str(folder / "vins_tum.txt"), str(folder / "ground_truth.tum"),
                                      "--t-max-diff", "0.1", "--rpe-relation", "point_distance", "--json", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert report["notes"] == [] and report["rpe"]["pose_relation"] == "point_distance"
    assert 0.0 < report["rpe"]["rmse"] < 0.2


def test_json_and_plots(small_pair, tmp_path):
    est, gt = small_pair
    out = tmp_path / "r" / "eval.json"
    plots = tmp_path / "plots"
    result = CliRunner().invoke(cli, ["eval", str(est), str(gt), "--align", "none", "--json", str(out),
                                      "--plot", str(plots), "--rpe-delta", "0.5"])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert report["ape"]["rmse"] == pytest.approx(0.1, abs=1e-9)
    assert report["ape"]["pairs"] == 41
    assert report["rpe"]["rmse"] == pytest.approx(0.0, abs=1e-9)
    assert report["estimate_path_length_m"] == pytest.approx(4.0)
    assert sorted(p.name for p in plots.iterdir()) == ["ape_over_time.png", "rpe_over_time.png", "top_view.png",
                                                       "xyz.png"]
    # se3 alignment removes the offset
    result = CliRunner().invoke(cli, ["eval", str(est), str(gt), "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert json.loads(out.read_text())["ape"]["rmse"] < 1e-9


def test_rpe_failure_is_reported_not_fatal(small_pair, tmp_path):
    est, gt = small_pair
    out = tmp_path / "eval.json"
    result = CliRunner().invoke(cli, ["eval", str(est), str(gt), "--rpe-delta", "50", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert "RPE not computed" in result.output
    report = json.loads(out.read_text())
    assert report["rpe"] is None and "delta 50" in report["rpe_error"]


def _assert_one_line_error(code, stdout, stderr, *fragments, expected=1):
    """One line on stderr naming the problem; exit code 1 for bad data, 2 for a usage error."""
    assert code == expected, (stdout, stderr)
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


def test_no_overlapping_time_stamps_exit_1_one_line(small_pair, tmp_path):
    est, _ = small_pair
    late = write(tmp_path / "late.txt", "5000.0 0 0 0 0 0 0 1\n5000.1 1 0 0 0 0 0 1\n5000.2 2 0 0 0 0 0 1\n")
    _assert_one_line_error(*run_linnet("eval", est, late), "no time stamps", "late.txt", "within 0.01 s")


def test_missing_file_exit_2_one_line(small_pair, tmp_path):
    _, gt = small_pair  # a path argument that does not exist is a usage error
    _assert_one_line_error(*run_linnet("eval", tmp_path / "missing.txt", gt), "missing.txt", expected=2)


def test_malformed_and_empty_files_exit_1_one_line(small_pair, tmp_path):
    _, gt = small_pair
    bad = write(tmp_path / "bad.txt", "1.0 0 0 0 0 0 0 1\n2.0 0 0 zero 0 0 0 1\n")
    _assert_one_line_error(*run_linnet("eval", bad, gt), "bad.txt:2:", "'zero' is not a number")
    empty = write(tmp_path / "empty.txt", "")
    _assert_one_line_error(*run_linnet("eval", gt, empty), "empty.txt", "no poses")


def test_bad_option_value_exit_2_one_line(small_pair):
    est, gt = small_pair
    _assert_one_line_error(*run_linnet("eval", est, gt, "--align", "rigid"), "--align", expected=2)
    _assert_one_line_error(*run_linnet("eval", est, gt, "--t-max-diff", "-1"), "--t-max-diff", expected=2)
