"""System test on a short simulator replay (known ground truth): the stereo-inertial pipeline end to end."""
import json

import pytest

from conftest import require_shared_data

# A 12 s stretch of EuRoC V1_02_medium's real motion (in flight: it starts 3 s in, after take-off begins),
# rendered in the room scene with EuRoC-level IMU noise.
START_S = 3.0
DURATION_S = 12.0
APE_BOUND_M = 0.05


@pytest.fixture(scope="module")
def replay_run(tmp_path_factory):
    import linnet
    from linnet import sim

    gt = require_shared_data("euroc_groundtruth/V1_02_medium.csv")
    data = tmp_path_factory.mktemp("replay") / "v102"
    sim.simulate(str(gt), "room", data, seed=3, start=START_S, duration=DURATION_S)
    out = tmp_path_factory.mktemp("replay_run")
    result = linnet.run_dataset(data, out=out)
    return result, out


def test_replay_is_tracked_from_initialisation_on(replay_run):
    result, _ = replay_run
    s = result["summary"]
    assert s["initialisation_time_s"] <= 1.0
    assert s["reinitialisations"] == 0
    assert s["frames_with_pose"] >= s["frames"] - round(s["initialisation_time_s"] * 20.0) - 1


def test_replay_trajectory_error_is_bounded(replay_run):
    result, out = replay_run
    s = json.loads((out / "summary.json").read_text())
    assert "ape" in s, s.get("ape_error")
    assert s["ape"]["rmse_m"] <= APE_BOUND_M, s["ape"]
    assert abs(s["path_length_m"] - s["gt_path_length_m"]) / s["gt_path_length_m"] < 0.05
