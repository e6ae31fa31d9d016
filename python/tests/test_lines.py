"""Line front-end from Python: ground-truth scoring functions, the LineTracker binding on synthetic frames, the
EuRoC reader, and the `linnet lines` / `linnet bench lines` commands on the real micro snippet."""
import json
import os
from pathlib import Path

import numpy as np
import pytest

from linnet import lines

REPO = Path(__file__).resolve().parents[2]


def _micro() -> Path:
    root = Path(os.environ.get("LINNET_SHARED_DATA", REPO.parent / "shared" / "data"))
    path = root / "euroc" / "V1_01_easy_micro"
    if not path.is_dir():
        if os.environ.get("CI") == "true":
            pytest.fail(f"shared data missing: {path}")
        pytest.skip(f"shared data missing: {path}")
    return path


# --- scoring functions -------------------------------------------------------------------------------------------


def _poly(a, b, n=20):
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)


def test_match_segment_tolerance_and_overlap():
    gt = _poly((100, 100), (300, 100))
    assert lines.match_segment([110, 101.5, 280, 98.5], gt)              # within 2 px, 85% of the segment
    assert not lines.match_segment([110, 102.5, 280, 100], gt)           # one endpoint 2.5 px away
    assert not lines.match_segment([100, 100, 180, 100], gt)             # covers only 40% of the segment
    assert lines.match_segment([100, 100, 180, 100], gt, overlap_of="shorter")  # but all of the detection is on it
    assert lines.match_segment([280, 100, 110, 100], gt)                 # orientation does not matter
    assert not lines.match_segment([100, 100, 300, 100], gt[:1])         # degenerate ground truth


def test_match_segment_follows_a_curved_projection():
    # A distorted projection: an arc of a large circle; the chord's endpoints lie on it.
    th = np.linspace(-0.3, 0.3, 60)
    gt = np.c_[400 + 1000 * np.sin(th), 1000 - 1000 * np.cos(th)]
    det = np.r_[gt[5], gt[54]]
    assert lines.match_segment(det, gt)


def test_detection_recall_and_assignment():
    gts = [_poly((0, 0), (100, 0)), _poly((0, 50), (100, 50)), _poly((0, 80), (30, 80))]  # the last is < 40 px
    dets = np.array([[5, 0.5, 95, 0.5], [0, 60, 100, 60]])
    assert lines.detection_recall(dets, gts) == (1, 2)
    assert lines.assign_segment(dets[0], gts) == 0
    assert lines.assign_segment(dets[1], gts) == -1
    assert lines.pair_precision([0, 1, -1, 2], [0, 2, 1, -1]) == (1, 2)


def test_parse_frames():
    assert lines.parse_frames(None, 10) == (0, 10)
    assert lines.parse_frames("2:5", 10) == (2, 5)
    assert lines.parse_frames("-3:", 10) == (7, 10)
    assert lines.parse_frames(":100", 10) == (0, 10)
    for bad in ("5", "a:b", "5:2"):
        with pytest.raises(ValueError):
            lines.parse_frames(bad, 10)


def test_percentile_table_and_colours():
    t = lines.percentile_table({"a": [1, 2, 3, 4, 100], "b": []})
    assert t["a"]["median"] == 3 and t["a"]["max"] == 100
    assert np.isnan(t["b"]["median"])
    assert lines.id_colour(7) == lines.id_colour(7) and lines.id_colour(7) != lines.id_colour(8)


# --- binding on synthetic frames -------------------------------------------------------------------------------


def _core():
    try:
        from linnet import _linnet
    except ImportError as e:  # the compiled module is part of every install; say why it is missing
        if os.environ.get("CI") == "true":
            pytest.fail(f"compiled core missing: {e}")
        pytest.skip(f"compiled core missing: {e}")
    if not hasattr(_linnet, "LineTracker"):
        pytest.skip("compiled core predates the line bindings")
    return _linnet


def _boxes(shift=0.0):
    import cv2

    img = np.full((480, 752), 70, np.uint8)
    rng = np.random.default_rng(4)
    for _ in range(12):
        x, y = rng.uniform(40, 600), rng.uniform(30, 350)
        w, h = rng.uniform(60, 150), rng.uniform(50, 120)
        pts = np.array([[x + shift, y], [x + w + shift, y + 0.2 * h], [x + w + shift, y + h], [x + shift, y + h]])
        cv2.fillConvexPoly(img, np.round(pts * 16).astype(np.int32), int(rng.integers(100, 250)), cv2.LINE_AA, 4)
    return cv2.GaussianBlur(img, (5, 5), 0.8)


PINHOLE = {"width": 752, "height": 480, "intrinsics": [450.0, 450.0, 375.5, 239.5], "distortion": "none",
           "distortion_coeffs": []}


def test_tracker_binding_tracks_a_shifting_scene():
    core = _core()
    T = np.eye(4)
    T[0, 3] = -0.11  # cam1 11 cm right of cam0
    tr = core.LineTracker(PINHOLE, PINHOLE, T, {"max_lines": 60})
    ids_prev = None
    for k in range(4):
        left = _boxes(3.0 * k)
        right = _boxes(3.0 * k - 12.0)  # a constant 12 px disparity: everything at fx * b / 12 = 4.1 m
        obs = tr.track(1_000_000 + k * 50_000_000, left, right)
        n = len(obs["id"])
        if k == 0:  # new lines are delivered from their second frame on (confirm_new)
            assert n == 0
            continue
        assert 10 <= n <= 60
        assert np.all(np.diff(obs["id"]) > 0)
        assert obs["ps0"].shape == (n, 2) and obs["s1"].shape == (n, 2)
        # Normalised = (pixel - c) / f for an undistorted pinhole.
        np.testing.assert_allclose(obs["s0"] * 450.0 + [375.5, 239.5], obs["ps0"], atol=1e-6)
        if ids_prev is not None:
            assert len(set(obs["id"]) & ids_prev) >= 0.7 * n
        ids_prev = set(obs["id"].tolist())
        m = obs["has_right"]
        assert m.sum() >= 0.5 * n
        # Right lines sit 12 px left of the left ones, along the normal at least.
        d0 = obs["pe0"][m] - obs["ps0"][m]
        nrm = np.c_[-d0[:, 1], d0[:, 0]] / np.linalg.norm(d0, axis=1)[:, None]
        off = ((obs["ps1"][m] - obs["ps0"][m]) * nrm).sum(1)
        expect = (np.array([-12.0, 0.0]) * nrm).sum(1)
        assert np.median(np.abs(off - expect)) < 1.0
    tm = tr.last_timings()
    assert tm["total_ms"] > 0 and tm["tracked"] > 0
    assert tr.options()["detection.detector"] == "ed"


def test_tracker_binding_errors_and_degenerate_images():
    core = _core()
    with pytest.raises(Exception, match="lines.nonsense"):
        core.LineTracker(PINHOLE, None, None, {"nonsense": 1})
    with pytest.raises(Exception, match="T_C1_C0"):
        core.LineTracker(PINHOLE, PINHOLE, None, {})
    tr = core.LineTracker(PINHOLE)
    for img in (np.zeros((480, 752), np.uint8), np.full((480, 752), 255, np.uint8),
                np.random.default_rng(1).integers(0, 256, (480, 752)).astype(np.uint8)):
        obs = tr.track(len(str(img.sum())), img)  # any increasing-enough time
        assert obs["id"].dtype == np.int64
    with pytest.raises(Exception):
        tr.track(10**12, np.zeros((10, 10), np.uint8))
    segs = core.detect_lines(_boxes(), {"detection.detector": "lsd", "detection.downsample": 1})
    assert segs.ndim == 2 and segs.shape[1] == 4 and len(segs) > 10


# --- real data and commands --------------------------------------------------------------------------------------


def test_euroc_reader():
    data = lines.EurocStereo(_micro())
    assert len(data) == 95 and data.stereo
    assert data.cam0["distortion"] == "radtan" and data.cam0["width"] == 752
    T = data.T_C1_C0
    assert abs(np.linalg.norm(T[:3, 3]) - 0.110) < 0.002
    t, left, right = next(data.frames(0, 1))
    assert left.shape == (480, 752) and right.shape == (480, 752) and left.dtype == np.uint8


def test_gyro_prediction(tmp_path):
    import shutil

    data = lines.EurocStereo(_micro())
    t0, t1 = data.images[0][0], data.images[1][0]
    R = data.gyro_prediction(t0, t1)
    assert R.shape == (3, 3) and np.allclose(R @ R.T, np.eye(3), atol=1e-9)
    assert np.allclose(data.gyro_prediction(t0, t0), np.eye(3))
    # Rates integrated over 50 ms: R is the camera-frame image of exp(w dt) (w: mean rate over the interval).
    imu = data.load_imu()
    keep = (imu.t_ns >= t0) & (imu.t_ns < t1)
    w_C = np.asarray(data.cam0["T_B_C"])[:3, :3].T @ imu.gyr[keep].mean(0)
    angle = np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))
    assert abs(angle - np.linalg.norm(w_C) * (t1 - t0) * 1e-9) < 2e-4
    assert data.gyro_prediction(t0 - 10**12, t1) is None  # not covered by the log
    # No imu0: no prediction. A malformed log: an error naming the file and line.
    copy = tmp_path / "ds"
    shutil.copytree(Path(data.root) / "mav0" / "cam0", copy / "mav0" / "cam0")
    assert lines.EurocStereo(copy).gyro_prediction(t0, t1) is None
    (copy / "mav0" / "imu0").mkdir()
    (copy / "mav0" / "imu0" / "data.csv").write_text("#t,wx,wy,wz,ax,ay,az\n1,0,0,0,0,0\n")
    with pytest.raises(lines.DatasetError, match=r"data.csv:2"):
        lines.EurocStereo(copy).load_imu()


def test_euroc_reader_errors(tmp_path):
    with pytest.raises(lines.DatasetError, match="sensor.yaml"):
        lines.EurocStereo(tmp_path)


def test_lines_and_bench_commands(tmp_path):
    _core()
    from click.testing import CliRunner

    from linnet.cli import cli

    micro = _micro()
    runner = CliRunner()
    res = runner.invoke(cli, ["lines", str(micro), "--out", str(tmp_path / "view"), "--frames", "0:6"])
    assert res.exit_code == 0, res.output
    pngs = sorted((tmp_path / "view").glob("frame_*.png"))
    assert len(pngs) == 6
    rows = np.loadtxt(tmp_path / "view" / "lines.csv", delimiter=",", comments="#")
    assert rows.shape == (6, 17) and rows[0, 2] == 0 and np.all(rows[1:, 2] >= 30)
    res = runner.invoke(cli, ["bench", "lines", str(micro), "--frames", "0:20", "--json", str(tmp_path / "b.json")])
    assert res.exit_code == 0, res.output
    assert "| detect |" in res.output
    out = json.loads((tmp_path / "b.json").read_text())
    assert out["frames"] == 20 and out["counts_median"]["lines"] >= 30
    assert out["stages_ms"]["total_ms"]["median"] > 0
    res = runner.invoke(cli, ["lines", str(micro), "--out", str(tmp_path / "x"), "--frames", "9:2"])
    assert res.exit_code != 0
    # Option overrides: a detector with its resolution, KEY=VALUE settings; errors name the setting or the key.
    res = runner.invoke(cli, ["bench", "lines", str(micro), "--frames", "0:3", "--detector", "edlines",
                              "--set", "detection.min_length_px=30", "--json", str(tmp_path / "c.json")])
    assert res.exit_code == 0, res.output
    opts = json.loads((tmp_path / "c.json").read_text())["options"]
    assert opts["detection.detector"] == "edlines" and opts["detection.downsample"] == 2.0
    assert opts["detection.parallel_edges"] is True and opts["detection.min_length_px"] == 30
    res = runner.invoke(cli, ["bench", "lines", str(micro), "--frames", "0:3", "--set", "detection.min_length_px"])
    assert res.exit_code != 0 and "KEY=VALUE" in res.output
    res = runner.invoke(cli, ["lines", str(micro), "--out", str(tmp_path / "y"), "--frames", "0:2", "--no-png",
                              "--set", "detection.bogus=1"])
    assert res.exit_code != 0 and "lines.detection.bogus" in res.output


def test_tracker_options():
    assert lines.tracker_options() == {}
    assert lines.tracker_options("lsd") == {"detection.detector": "lsd", "detection.downsample": 1.0,
                                            "detection.parallel_edges": False}
    # The half-size detectors come with the parallel-edge search, which recovers the thin bars' fused edges.
    assert lines.tracker_options("fld")["detection.parallel_edges"] is True
    opts = lines.tracker_options("ed", ["detection.parallel_edges=true", "temporal.guided_px = 2.5"])
    assert opts["detection.parallel_edges"] is True and opts["temporal.guided_px"] == 2.5
    with pytest.raises(ValueError, match="hough"):
        lines.tracker_options("hough")
    with pytest.raises(ValueError, match="KEY=VALUE"):
        lines.tracker_options(None, ["=3"])


def test_segment_labels_accept_parallel_true_edges_closer_than_the_tolerance():
    # Two true edges 1.5 px apart (the front and back edge of a thin frame) and one far away.
    gt = [(7, _poly((0, 0), (100, 0))), (8, _poly((0, 1.5), (100, 1.5))), (9, _poly((0, 40), (100, 40)))]
    assert lines.segment_labels([10, 0.2, 90, 0.2], gt) == {7, 8}
    assert lines.segment_labels([10, 1.4, 90, 1.4], gt) == {7, 8}
    assert lines.segment_labels([10, 40, 90, 40.5], gt) == {9}
    assert lines.segment_labels([10, 20, 90, 20], gt) == set()
    assert lines._judge({7, 8}, {8}) == (1, 1)
    assert lines._judge({7}, {9}) == (0, 1)
    assert lines._judge(set(), {9}) == (0, 0)


def test_bench_lines_on_the_simulator(tmp_path):
    _core()
    traj = Path(os.environ.get("LINNET_SHARED_DATA", REPO.parent / "shared" / "data")) / "euroc_groundtruth" / \
        "V1_02_medium.txt"
    if not traj.is_file():
        if os.environ.get("CI") == "true":
            pytest.fail(f"shared data missing: {traj}")
        pytest.skip(f"shared data missing: {traj}")
    from click.testing import CliRunner

    from linnet.cli import cli

    res = CliRunner().invoke(cli, ["bench", "lines", "--sim", "room", "--trajectory", str(traj), "--duration", "1",
                                   "--json", str(tmp_path / "s.json")])
    assert res.exit_code == 0, res.output
    out = json.loads((tmp_path / "s.json").read_text())
    assert out["frames"] >= 20
    assert out["temporal_judged"] > 100 and out["stereo_judged"] > 100
    assert out["temporal_precision"] >= 0.95 and out["stereo_precision"] >= 0.95
    assert 0.2 <= out["detection_recall"] <= 1.0
    tc = out["track_consistency"]
    assert tc["tracks_scored"] > 10 and tc["median_px"] < 1.0


def test_detection_recall_measures_endpoints_to_the_projected_line():
    # Visible part ends at x=100 (sampled run end); the detection runs on along the true line to x=104.
    run = _poly((0, 0), (100, 0))
    full = _poly((-50, 0), (300, 0), 200)
    det = np.array([[10, 0.5, 104, 0.5]])
    assert lines.detection_recall(det, [run]) == (0, 1)
    assert lines.detection_recall(det, [run], full_lines=[full]) == (1, 1)
    assert lines.detection_recall(np.array([[10, 2.5, 104, 2.5]]), [run], full_lines=[full]) == (0, 1)


def test_projected_line_passes_through_the_segment():
    from linnet.sim.rig import EUROC_CAM0, project

    a, b = np.array([-0.5, 0.2, 2.0]), np.array([0.6, 0.1, 3.0])
    full = lines._projected_line(EUROC_CAM0, a, b, 752, 480)
    seg = project(EUROC_CAM0, a + np.linspace(0, 1, 20)[:, None] * (b - a))
    assert len(full) > 100
    assert max(lines._polyline_param(full, p)[0] for p in seg) < 0.05


def _synthetic_tracks(shift_px: float = 0.0, focal: float = 460.0):
    """Two 3D lines seen from 8 camera poses moving sideways (cam0, identity rotation): {id: sightings}. With
    shift_px, track 1's sighting in frame 4 is moved that far across its line."""
    rng = np.random.default_rng(3)
    lines_W = [(np.array([-0.5, -0.4, 3.0]), np.array([0.6, 0.5, 3.5])),
               (np.array([0.3, -0.6, 2.5]), np.array([0.2, 0.7, 4.0]))]
    tracks = {0: [], 1: []}
    for k in range(8):
        T = np.eye(4)
        T[:3, 3] = [0.08 * k, 0.01 * k, 0.0]
        for tid, (a, b) in enumerate(lines_W):
            ac, bc = a - T[:3, 3], b - T[:3, 3]
            s, e = ac[:2] / ac[2], bc[:2] / bc[2]
            s = s + rng.normal(0.0, 0.1 / focal, 2)
            e = e + rng.normal(0.0, 0.1 / focal, 2)
            if tid == 1 and k == 4 and shift_px:
                d = (e - s) / np.linalg.norm(e - s)
                nrm = np.array([-d[1], d[0]])
                s, e = s + shift_px / focal * nrm, e + shift_px / focal * nrm
            tracks[tid].append((k, T, s, e))
    return tracks


def test_track_consistency_finds_a_sighting_off_its_tracks_line():
    clean = lines.track_consistency(_synthetic_tracks(), 460.0)
    assert clean["tracks_scored"] == 2 and clean["sightings"] == 16
    assert clean["median_px"] < 0.3 and clean["share_above_px"] == 0.0
    assert clean["tracks_with_bad_sighting"] == 0.0
    moved = lines.track_consistency(_synthetic_tracks(shift_px=6.0), 460.0)
    assert moved["share_above_px"] == pytest.approx(1 / 16)  # only the moved sighting
    assert moved["tracks_with_bad_sighting"] == pytest.approx(0.5)
    assert moved["median_px"] < 0.3  # the others still fit their lines
    # Too short tracks are not scored.
    assert lines.track_consistency(_synthetic_tracks(), 460.0, min_frames=9)["tracks_scored"] == 0
