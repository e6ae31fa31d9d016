"""Online calibration end to end: a short replay whose camera stamps are 5 ms late (`--time-offset-ms 5`) and whose
written extrinsics are off; the default config recovers the time offset, and the extrinsics option reports a
correction towards the truth. summary.json carries both."""
import json

import numpy as np
import pytest

from conftest import require_shared_data

START_S = 3.0
DURATION_S = 10.0
OFFSET_MS = 5.0


@pytest.fixture(scope="module")
def offset_replay(tmp_path_factory):
    from linnet import sim

    gt = require_shared_data("euroc_groundtruth/V1_02_medium.csv")
    data = tmp_path_factory.mktemp("offset") / "v102"
    sim.simulate(str(gt), "room", data, seed=5, start=START_S, duration=DURATION_S, time_offset_ms=OFFSET_MS)
    return data


def test_time_offset_is_recovered_with_the_default_config(offset_replay, tmp_path):
    import linnet

    result = linnet.run_dataset(offset_replay, out=tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "ok", s["problems"]
    assert s["reinitialisations"] == 0
    assert abs(s["time_offset_ms"] - OFFSET_MS) < 1.0, s["time_offset_ms"]
    assert result["summary"]["time_offset_ms"] == s["time_offset_ms"]
    # The rig's extrinsics are refined by default too. The replay's calibration is exact: the correction stays small.
    c = s["extrinsics_correction"]
    T = np.array(c["T_B_R"])
    assert T.shape == (4, 4)
    np.testing.assert_allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-9)
    assert c["rotation_deg"] < 0.3 and c["translation_m"] < 0.01, c
    # So is cam1 relative to cam0, exact here too: hundredths of a degree at most.
    c1 = s["stereo_correction"]
    assert np.array(c1["S"]).shape == (4, 4)
    assert c1["rotation_deg"] < 0.05 and c1["translation_m"] < 0.001, c1


def test_extrinsics_correction_is_absent_when_off(offset_replay, tmp_path):
    import linnet

    from linnet.api import load_config

    config = load_config(offset_replay, overrides=["estimator.extrinsics.estimate=false"])
    linnet.run_dataset(offset_replay, config, out=tmp_path)
    s = json.loads((tmp_path / "summary.json").read_text())
    assert s["status"] == "ok", s["problems"]
    assert "extrinsics_correction" not in s
    assert "stereo_correction" not in s
