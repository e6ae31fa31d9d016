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
    assert (out / "odometry.tum").is_file()
    assert s["reinitialisations"] == 0


def test_loop_corrected_trajectory_stays_accurate(loop_run):
    from linnet import evaluation as ev

    data, out, _ = loop_run
    gt = ev.load_trajectory(data / "mav0" / "state_groundtruth_estimate0" / "data.csv")
    corrected = ev.ape(ev.load_trajectory(out / "trajectory.tum"), gt, align="se3", t_max_diff=0.01).rmse
    odometry = ev.ape(ev.load_trajectory(out / "odometry.tum"), gt, align="se3", t_max_diff=0.01).rmse
    assert odometry <= 0.02, odometry
    assert corrected <= 0.02, (corrected, odometry)
