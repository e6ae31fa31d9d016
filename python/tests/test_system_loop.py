"""System test of loop closure on a simulated figure-eight flight that comes back to its start (builtin:loop, room).

The replay lasts long enough for the flight to pass its first stretch again more than loop.min_time_gap_s later: the
loop closer must find that place, and the loop-corrected trajectory must stay accurate. On this clean replay the
odometry drifts less than a loop measurement's error (1-3 cm), so the correction cannot gain much here (0.0075 ->
0.0094 m when written; docs/known_issues.md); on the hard replays it does (README "Loop closure")."""
import json

import pytest

DURATION_S = 32.0


@pytest.fixture(scope="module")
def loop_run(tmp_path_factory):
    import linnet
    from linnet import sim

    data = tmp_path_factory.mktemp("loop") / "fig8"
    sim.simulate("builtin:loop", "room", data, seed=4, duration=DURATION_S)
    out = tmp_path_factory.mktemp("loop_run")
    result = linnet.run_dataset(data, out=out)  # the default config: loop closure on
    return data, out, result


def test_loops_are_closed_and_reported(loop_run):
    import yaml

    import linnet

    _, out, result = loop_run
    min_inliers = yaml.safe_load(linnet.Config.euroc_stereo_imu().to_yaml())["loop"]["min_inliers"]
    s = json.loads((out / "summary.json").read_text())
    lc = s["loop_closure"]
    assert lc["loops"] >= 1, lc
    for e in lc["events"]:
        assert e["t_new_s"] - e["t_old_s"] >= 20.0
        assert e["inliers"] >= min_inliers
    # The database's counts: every graph node is a keyframe, every description a graph node's; its memory is reported.
    assert lc["keyframes"] >= lc["graph_nodes"] >= lc["described"] >= 1
    assert 0.0 < lc["place_mb"] < 0.1 * lc["described"]  # under 100 KB per description
    assert (out / "odometry.tum").is_file()
    assert s["reinitialisations"] == 0


def test_loops_csv_holds_each_loops_measured_relative_pose(loop_run):
    import numpy as np

    from linnet import loop_eval

    data, out, _ = loop_run
    events = json.loads((out / "summary.json").read_text())["loop_closure"]["events"]
    loops = loop_eval.read_loops(out / "loops.csv")
    assert len(loops) == len(events)
    assert list(loops.methods) == [e["method"] for e in events]
    assert set(loops.methods) <= {"descriptors", "guided", "lines"}
    for k, event in enumerate(events):
        assert abs(1e-9 * loops.t_new_ns[k] - event["t_new_s"]) < 1e-6
        assert abs(1e-9 * loops.t_old_ns[k] - event["t_old_s"]) < 1e-6
        assert loops.inliers[k] == event["inliers"]
        assert np.allclose(loops.p[k], np.array(event["T_old_new"])[:3, 3], rtol=0, atol=1e-12)
        # The edge's sigmas: at least the configured floor (1 cm, 0.2 deg), as in summary.json.
        assert loops.sigma_m[k] == event["sigma_m"] >= 0.01 and loops.sigma_yaw_deg[k] == event["sigma_yaw_deg"] >= 0.2
    # Against the ground truth (`linnet eval-loops`): the weakest loops here (15-20 inliers) are off by up to about
    # 11 cm and 2 deg when written; a frame convention error would be off by the loop's whole baseline (0.1-1 m).
    report = loop_eval.evaluate_run_loops(out, data)
    errors = [e["position_error_m"] for e in report["loops"]]
    assert max(errors) < 0.15, report["worst"]
    assert max(e["rotation_error_deg"] for e in report["loops"]) < 3.0, report["worst"]
    assert report["groups"][0]["position_rmse_m"] < 0.08, errors


def test_loop_corrected_trajectory_stays_accurate(loop_run):
    from linnet import evaluation as ev

    data, out, _ = loop_run
    gt = ev.load_trajectory(data / "mav0" / "state_groundtruth_estimate0" / "data.csv")
    corrected = ev.ape(ev.load_trajectory(out / "trajectory.tum"), gt, align="se3", t_max_diff=0.01).rmse
    odometry = ev.ape(ev.load_trajectory(out / "odometry.tum"), gt, align="se3", t_max_diff=0.01).rmse
    assert odometry <= 0.02, odometry
    assert corrected <= 0.02, (corrected, odometry)
