"""Tests of linnet.loop_eval and ``linnet eval-loops``: loops.csv reading, each loop's error against an interpolated
ground truth, the summary by method and inliers, and the command's output and errors."""
from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.spatial.transform import Rotation

from linnet import evaluation as ev
from linnet import loop_eval
from linnet.evaluation import InputError

HEADER = ("#t_new [ns],t_old [ns],inliers,correction [m],correction_yaw [deg],x [m],y [m],z [m],qx,qy,qz,qw,"
          "sigma [m],sigma_yaw [deg],method\n")
T0 = 1_600_000_000_000_000_000
RATE_HZ = 200.0


def truth_at(t_s):
    """The ground truth's body pose at t_s seconds: a helix with a turning, rolling body (smooth, so that linear /
    spherical interpolation between 200 Hz samples is exact to well under a micrometre / microradian)."""
    t_s = np.atleast_1d(np.asarray(t_s, dtype=float))
    p = np.stack([2.0 * np.cos(0.3 * t_s), 1.5 * np.sin(0.3 * t_s), 0.1 * t_s], axis=1)
    R = Rotation.from_euler("zyx", np.stack([0.3 * t_s + 1.0, 0.1 * np.sin(t_s), 0.2 * np.cos(0.7 * t_s)], axis=1))
    return R, p


@pytest.fixture
def ground_truth(tmp_path):
    """A EuRoC-format ground truth of 20 s at 200 Hz in a dataset folder."""
    t_s = np.arange(int(20.0 * RATE_HZ) + 1) / RATE_HZ
    R, p = truth_at(t_s)
    q = R.as_quat()  # x, y, z, w
    folder = tmp_path / "dataset" / "mav0" / "state_groundtruth_estimate0"
    folder.mkdir(parents=True)
    rows = [f"{T0 + round(t * 1e9)},{x:.12f},{y:.12f},{z:.12f},{qq[3]:.12f},{qq[0]:.12f},{qq[1]:.12f},{qq[2]:.12f},"
            "0,0,0,0,0,0,0,0,0" for t, (x, y, z), qq in zip(t_s, p, q)]
    header = "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z,v_x,v_y,v_z,bw_x,bw_y,bw_z,ba_x,ba_y,ba_z\n"
    (folder / "data.csv").write_text(header + "\n".join(rows) + "\n")
    return tmp_path / "dataset"


def loop_row(t_new_s, t_old_s, inliers=40, method="descriptors", dp=(0.0, 0.0, 0.0), drot_deg=0.0, sigma=0.01):
    """A loops.csv row measuring the true relative pose, off by dp (m, in the old body's frame) and by a rotation of
    drot_deg about z."""
    R_old, p_old = truth_at(t_old_s)
    R_new, p_new = truth_at(t_new_s)
    p = R_old.inv().apply(p_new - p_old)[0] + np.asarray(dp)
    R = (R_old.inv() * R_new * Rotation.from_euler("z", drot_deg, degrees=True))[0]
    q = R.as_quat()
    return (f"{T0 + round(t_new_s * 1e9)},{T0 + round(t_old_s * 1e9)},{inliers},0.01,0.1,{p[0]:.12f},{p[1]:.12f},"
            f"{p[2]:.12f},{q[0]:.12f},{q[1]:.12f},{q[2]:.12f},{q[3]:.12f},{sigma},0.2,{method}\n")


@pytest.fixture
def run_dir(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    rows = [loop_row(12.5, 1.0),                                                     # exact, on samples
            loop_row(14.1234, 2.0017, inliers=16, method="lines", dp=(0.03, 0.0, -0.04)),  # 5 cm, between samples
            loop_row(17.3, 3.3, inliers=25, method="guided", drot_deg=0.5),
            loop_row(19.0, 4.0, inliers=17, method="lines", dp=(0.0, 0.2, 0.0), sigma=0.02)]  # 10 sigma
    (run / "loops.csv").write_text(HEADER + "".join(rows))
    return run


def test_read_loops_reads_every_column(run_dir):
    loops = loop_eval.read_loops(run_dir / "loops.csv")
    assert len(loops) == 4
    assert loops.t_new_ns[0] == T0 + 12_500_000_000 and loops.t_old_ns[1] == T0 + 2_001_700_000
    assert list(loops.inliers) == [40, 16, 25, 17]
    assert loops.methods == ("descriptors", "lines", "guided", "lines")
    assert np.allclose(np.linalg.norm(loops.q_wxyz, axis=1), 1.0)
    assert list(loops.sigma_m) == [0.01, 0.01, 0.01, 0.02] and list(loops.sigma_yaw_deg) == [0.2] * 4


def test_read_loops_header_only_and_errors(tmp_path):
    f = tmp_path / "loops.csv"
    f.write_text(HEADER)
    assert len(loop_eval.read_loops(f)) == 0
    good = loop_row(12.5, 1.0)
    for bad, message in [(good.replace(",descriptors", ""), "loops.csv:2: 14 columns, expected 15"),
                         (good.replace(",40,", ",forty,", 1), "loops.csv:2: inliers 'forty' is not an integer"),
                         (good.replace(",0.01,0.2,", ",-0.01,0.2,"), "loops.csv:2: sigma -0.01 is negative")]:
        f.write_text(HEADER + bad)
        with pytest.raises(InputError, match=message):
            loop_eval.read_loops(f)
    tokens = good.strip().split(",")
    tokens[11] = "2.0"  # qw: not a unit quaternion
    f.write_text(HEADER + "\n" + ",".join(tokens) + "\n")
    with pytest.raises(InputError, match="loops.csv:3: quaternion norm"):
        loop_eval.read_loops(f)
    with pytest.raises(InputError, match="nothere.csv"):
        loop_eval.read_loops(tmp_path / "nothere.csv")


def test_loop_errors_against_the_interpolated_truth(run_dir, ground_truth):
    loops = loop_eval.read_loops(run_dir / "loops.csv")
    gt = ev.load_trajectory(ground_truth / "mav0" / "state_groundtruth_estimate0" / "data.csv")
    e = loop_eval.loop_errors(loops, gt)
    # Between samples the interpolated truth is within a micrometre of the analytic one.
    assert e["position_m"] == pytest.approx([0.0, 0.05, 0.0, 0.2], abs=2e-6)
    assert e["rotation_deg"] == pytest.approx([0.0, 0.0, 0.5, 0.0], abs=2e-4)
    assert e["sigmas"] == pytest.approx([0.0, 5.0, 0.0, 10.0], abs=1e-3)


def test_loop_errors_need_a_ground_truth_pose_near_each_keyframe(run_dir, ground_truth):
    gt = ev.load_trajectory(ground_truth / "mav0" / "state_groundtruth_estimate0" / "data.csv")
    short = ev.time_slice(gt, gt.t_ns[0], T0 + 15_000_000_000)
    message = r"no ground-truth pose within 0.01 s of the new keyframe at \d+ ns \(loop 3\)"
    with pytest.raises(InputError, match=message):
        loop_eval.loop_errors(loop_eval.read_loops(run_dir / "loops.csv"), short)


def test_summary_by_method_and_inlier_band(run_dir, ground_truth):
    loops = loop_eval.read_loops(run_dir / "loops.csv")
    gt = ev.load_trajectory(ground_truth / "mav0" / "state_groundtruth_estimate0" / "data.csv")
    groups = loop_eval.summarise(loops, loop_eval.loop_errors(loops, gt))
    assert [(g["method"], g["inliers"], g["loops"]) for g in groups] == [
        ("all", "all", 4), ("descriptors", ">= 30", 1), ("guided", "20-29", 1), ("lines", "< 20", 2)]
    lines = groups[3]
    assert lines["position_rmse_m"] == pytest.approx(np.sqrt((0.05 ** 2 + 0.2 ** 2) / 2), abs=1e-5)
    assert lines["position_max_m"] == pytest.approx(0.2, abs=1e-5)
    assert lines["beyond_3_sigma"] == 1.0 and lines["sigma_median_m"] == pytest.approx(0.015)
    assert groups[0]["beyond_3_sigma"] == 0.5
    one_band = loop_eval.summarise(loops, loop_eval.loop_errors(loops, gt), bands=(17,))
    assert [(g["method"], g["inliers"]) for g in one_band][1:] == [
        ("descriptors", ">= 17"), ("guided", ">= 17"), ("lines", "< 17"), ("lines", ">= 17")]
    with pytest.raises(ValueError, match="increasing"):
        loop_eval.summarise(loops, loop_eval.loop_errors(loops, gt), bands=(30, 20))


def cli():
    from linnet.cli import cli as command_group

    return command_group


def test_eval_loops_command_prints_the_summary_and_writes_json(run_dir, ground_truth, tmp_path):
    out = tmp_path / "out" / "loops.json"
    png = tmp_path / "plots" / "loops.png"
    result = CliRunner().invoke(cli(), ["eval-loops", str(run_dir), str(ground_truth), "--worst", "2",
                                        "--json", str(out), "--plot", str(png)])
    assert result.exit_code == 0, result.output
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 5000
    for text in ("method", "lines", "< 20", "200.0 mm (10.0 sigma of 20.0 mm)", "largest position errors"):
        assert text in result.output, text
    report = json.loads(out.read_text())
    assert len(report["loops"]) == 4 and len(report["worst"]) == 2
    assert report["worst"][0]["position_error_m"] == pytest.approx(0.2, abs=1e-5)
    assert report["groups"][0]["loops"] == 4
    # A ground-truth file works as well as the dataset folder.
    gt_file = ground_truth / "mav0" / "state_groundtruth_estimate0" / "data.csv"
    result = CliRunner().invoke(cli(), ["eval-loops", str(run_dir), str(gt_file)])
    assert result.exit_code == 0, result.output


def test_eval_loops_command_errors_are_one_line(run_dir, ground_truth):
    (run_dir / "loops.csv").unlink()
    result = CliRunner().invoke(cli(), ["eval-loops", str(run_dir), str(ground_truth)])
    assert result.exit_code == 1
    assert "loops.csv: no such file" in result.output and len(result.output.strip().splitlines()) == 1
    result = CliRunner().invoke(cli(), ["eval-loops", str(run_dir), str(ground_truth), "--bands", "30,20"])
    assert result.exit_code == 2 and "--bands" in result.output
    (run_dir / "loops.csv").write_text(HEADER)
    result = CliRunner().invoke(cli(), ["eval-loops", str(run_dir), str(ground_truth)])
    assert result.exit_code == 0 and "holds no loop" in result.output
    assert "eval-loops" in CliRunner().invoke(cli(), ["--help"]).output
