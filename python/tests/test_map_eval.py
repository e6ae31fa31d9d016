"""Tests of linnet.map_eval and ``linnet eval-map``: map_lines.csv reading, association and metrics of map lines
against true segments, the run-folder evaluation with the SE3 alignment, and the command."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

from linnet import map_eval
from linnet.evaluation import InputError

HEADER = "#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations\n"

# True segments in the ground-truth frame G.
TRUE = np.array([
    [[0.0, 0.0, 0.0], [2.0, 0.0, 0.0]],  # 0: along x
    [[0.0, 3.0, 0.0], [0.0, 3.0, 2.0]],  # 1: vertical at (0, 3)
    [[5.0, 0.0, 1.0], [5.0, 2.0, 1.0]],  # 2: along y
    [[-3.0, -3.0, 0.0], [-1.0, -1.0, 1.0]],  # 3: oblique
    [[10.0, 0.3, 0.0], [12.0, 0.3, 0.0]],  # 4: parallel to 0, 0.3 m aside, far along x
])

TILT_DEG = 2.0
S2 = math.sin(math.radians(TILT_DEG))
C2 = math.cos(math.radians(TILT_DEG))


def _oblique_offset(distance: float) -> np.ndarray:
    """Segment 3 moved by ``distance`` perpendicular to its direction."""
    u = TRUE[3, 1] - TRUE[3, 0]
    n = np.cross(u, [0.0, 0.0, 1.0])
    n /= np.linalg.norm(n)
    mid = TRUE[3].mean(axis=0)
    return np.array([mid - 0.3 * u + distance * n, mid + 0.3 * u + distance * n])


# Map segments in G, with the expected true index, angle and endpoint distances to the true infinite line.
MAP_G = np.array([
    [[0.5, 0.0, 0.0], [1.5, 0.0, 0.0]],  # on 0
    [[5.0, 1.0 - 0.5 * C2, 1.0 - 0.5 * S2], [5.0, 1.0 + 0.5 * C2, 1.0 + 0.5 * S2]],  # 2 tilted by 2 deg
    [[0.03, 3.0, 0.5], [0.03, 3.0, 1.5]],  # 1 shifted by 3 cm
    _oblique_offset(0.1),  # 3 shifted by 10 cm
    [[10.2, 0.0, 0.0], [11.8, 0.0, 0.0]],  # on 0's infinite line, but nearest to the finite segment 4
])
EXPECTED_INDEX = [0, 2, 1, 3, 4]
EXPECTED_ANGLE = [0.0, TILT_DEG, 0.0, 0.0, 0.0]
EXPECTED_DIST = [0.0, 0.5 * S2, 0.03, 0.1, 0.3]


def rotation(axis, deg: float) -> np.ndarray:
    """Rodrigues: rotation by ``deg`` degrees about ``axis``."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = math.radians(deg)
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


def rigid(R, t) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


# W -> G: the estimator's world frame is rotated by 40 deg about an oblique axis and shifted.
AXIS, ANGLE = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0]), 40.0
T_GT_W = rigid(rotation(AXIS, ANGLE), [1.5, -2.0, 0.7])
T_W_GT = np.linalg.inv(T_GT_W)
MAP_W = map_eval.transform_segments(T_W_GT, MAP_G)


# ------------------------------------------------------------------------------------------------------ scoring


def test_score_recovers_association_angles_and_distances():
    score = map_eval.score_line_map(MAP_W, TRUE, T_gt_W=T_GT_W)
    assert score.count == 5 and score.true_lines_total == 5 and score.true_lines_associated == 5
    assert score.true_index.tolist() == EXPECTED_INDEX
    assert score.angle_deg == pytest.approx(EXPECTED_ANGLE, abs=1e-9)
    assert score.angle_deg[1] == pytest.approx(2.0, abs=1e-9)
    assert score.endpoint_dist_m == pytest.approx(np.repeat(np.array(EXPECTED_DIST)[:, None], 2, axis=1), abs=1e-9)
    assert np.allclose(score.segments, MAP_G, atol=1e-12)
    # the association distance is to the finite segment: 0 on segment 0, 0.3 m to segment 4 for the last line
    assert score.association_dist_m[[0, 4]] == pytest.approx([0.0, 0.3], abs=1e-12)
    all_dist = np.repeat(EXPECTED_DIST, 2)
    assert score.median_angle_deg == pytest.approx(0.0, abs=1e-9)
    assert score.median_endpoint_dist_m == pytest.approx(0.03, abs=1e-9)
    assert score.p90_endpoint_dist_m == pytest.approx(np.percentile(all_dist, 90), abs=1e-9)
    assert score.within_m == 0.05
    assert score.frac_within == pytest.approx(3 / 5)  # 0, 0.017 and 0.03 m
    assert map_eval.score_line_map(MAP_W, TRUE, T_GT_W, within_m=0.02).frac_within == pytest.approx(2 / 5)
    assert map_eval.score_line_map(MAP_W, TRUE, T_GT_W, within_m=0.3).frac_within == pytest.approx(1.0)
    # coverage: the true lines with a map line within the bound
    assert score.true_lines_mapped == 3 and score.summary()["true_lines_mapped"] == 3
    assert map_eval.score_line_map(MAP_W, TRUE, T_GT_W, within_m=0.02).true_lines_mapped == 2
    assert map_eval.score_line_map(MAP_W, TRUE, T_GT_W, within_m=0.3).true_lines_mapped == 5


def test_median_association_distance():
    score = map_eval.score_line_map(MAP_W, TRUE, T_GT_W)
    assert score.median_association_dist_m == pytest.approx(np.median(score.association_dist_m), abs=1e-12)
    assert score.summary()["median_association_dist_m"] == pytest.approx(score.median_association_dist_m)
    # map lines 1 m from every true segment
    far = map_eval.score_line_map(MAP_G + np.array([0.0, 0.0, 1.0]), TRUE)
    assert far.median_association_dist_m > 0.5


def test_coverage_counts_each_true_line_once():
    # a second, exact copy of every map line: twice the lines, the same true lines mapped
    score = map_eval.score_line_map(np.concatenate([MAP_G, MAP_G]), TRUE)
    assert score.count == 10 and score.true_lines_associated == 5 and score.true_lines_mapped == 3
    assert score.frac_within == pytest.approx(3 / 5)


def test_without_transform_the_frames_coincide():
    score = map_eval.score_line_map(MAP_G, TRUE)
    assert score.true_index.tolist() == EXPECTED_INDEX
    assert score.angle_deg == pytest.approx(EXPECTED_ANGLE, abs=1e-9)
    # in the wrong frame the same map does not fit
    assert map_eval.score_line_map(MAP_W, TRUE).median_endpoint_dist_m > 0.2


@pytest.mark.parametrize("deg, expected", [(0.0, 0.0), (0.01, 0.01), (2.0, 2.0), (45.0, 45.0), (90.0, 90.0),
                                           (120.0, 60.0), (180.0, 0.0), (-30.0, 30.0)])
def test_angle_is_between_0_and_90_degrees(deg, expected):
    d = rotation([0, 0, 1], deg) @ [1.0, 0.0, 0.0]
    seg = np.array([[[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]]) + np.array([-0.2 * d, 0.2 * d])[None]
    score = map_eval.score_line_map(seg, TRUE[:1])
    assert score.angle_deg[0] == pytest.approx(expected, abs=1e-9)
    # both endpoints lie symmetric about (1, 0, 0) on line 0: distance 0.2 |sin(angle)|
    assert score.endpoint_dist_m[0] == pytest.approx([0.2 * abs(math.sin(math.radians(deg)))] * 2, abs=1e-12)


def test_reversed_map_segment_scores_the_same():
    a = map_eval.score_line_map(MAP_W, TRUE, T_GT_W)
    b = map_eval.score_line_map(MAP_W[:, ::-1], TRUE, T_GT_W)
    assert a.true_index.tolist() == b.true_index.tolist()
    assert a.angle_deg == pytest.approx(b.angle_deg, abs=1e-9)
    assert a.endpoint_dist_m == pytest.approx(b.endpoint_dist_m[:, ::-1], abs=1e-12)


def test_ties_go_to_the_lowest_index():
    truth = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]])
    seg = np.array([[[0.5, 0.1, 0.0], [1.5, 0.1, 0.0]]])  # straddles the joint of two collinear segments
    assert map_eval.score_line_map(seg, truth).true_index.tolist() == [0]
    assert map_eval.score_line_map(seg, truth[::-1]).true_index.tolist() == [0]


def _brute_force_association(segs, truth):
    def dist(p, a, b):
        d = b - a
        t = min(1.0, max(0.0, float(np.dot(p - a, d) / np.dot(d, d))))
        return float(np.linalg.norm(p - (a + t * d)))

    return [int(np.argmin([0.5 * (dist(s[0], *tr) + dist(s[1], *tr)) for tr in truth])) for s in segs]


def test_association_matches_brute_force_and_chunking_changes_nothing(monkeypatch):
    rng = np.random.default_rng(7)
    truth = rng.uniform(-5, 5, size=(60, 2, 3))
    segs = rng.uniform(-5, 5, size=(45, 2, 3))
    full = map_eval.score_line_map(segs, truth)
    assert full.true_index.tolist() == _brute_force_association(segs, truth)
    monkeypatch.setattr(map_eval, "_CHUNK_ELEMENTS", 100)  # blocks of 1 map line
    chunked = map_eval.score_line_map(segs, truth)
    assert chunked.true_index.tolist() == full.true_index.tolist()
    assert np.array_equal(chunked.endpoint_dist_m, full.endpoint_dist_m)
    assert np.array_equal(chunked.association_dist_m, full.association_dist_m)


def test_empty_map_gives_count_zero_and_no_figures():
    score = map_eval.score_line_map(np.zeros((0, 2, 3)), TRUE)
    assert score.count == 0 and score.true_index.shape == (0,) and score.endpoint_dist_m.shape == (0, 2)
    assert math.isnan(score.median_angle_deg) and math.isnan(score.frac_within)
    summary = score.summary()
    assert summary["count"] == 0 and summary["median_angle_deg"] is None and summary["frac_within"] is None
    json.dumps(summary)


@pytest.mark.parametrize("args, pattern", [
    ((np.zeros((2, 3)), TRUE), r"segments_W must have shape \(N, 2, 3\)"),
    ((MAP_G, TRUE[:, :1]), r"true_segments must have shape"),
    ((np.array([[[0, 0, 0], [0, 0, 0.0]]]), TRUE), r"segments_W: segment 0 is shorter than"),
    ((MAP_G, np.array([[[0, 0, 0], [1, np.nan, 0.0]]])), r"true_segments: non-finite coordinate in segment 0"),
    ((MAP_G, np.zeros((0, 2, 3))), r"no true segments"),
    ((MAP_G, TRUE, np.eye(3)), r"T_gt_W must be a 4x4 matrix"),
    ((MAP_G, TRUE, rigid(2 * np.eye(3), [0, 0, 0])), r"not a rotation"),
    ((MAP_G, TRUE, rigid(np.diag([1.0, 1.0, -1.0]), [0, 0, 0])), r"not a rotation"),
])
def test_score_rejects_bad_input(args, pattern):
    with pytest.raises(ValueError, match=pattern):
        map_eval.score_line_map(*args)


@pytest.mark.parametrize("within_m", [-1.0, math.nan, math.inf])
def test_score_rejects_bad_within(within_m):
    with pytest.raises(ValueError, match="within_m must be a finite number >= 0 m"):
        map_eval.score_line_map(MAP_G, TRUE, within_m=within_m)


# -------------------------------------------------------------------------------------------------- map_lines.csv


def write_map_lines(path, segments, observations, ids=None):
    ids = range(100, 100 + len(segments)) if ids is None else ids
    with open(path, "w", encoding="utf-8") as f:
        f.write(HEADER)
        for i, s, n in zip(ids, segments, observations):
            f.write(f"{i}," + ",".join(f"{v:.12f}" for v in s.ravel()) + f",{n}\n")
    return path


def test_read_map_lines(tmp_path):
    f = write_map_lines(tmp_path / "map_lines.csv", MAP_W, [17, 3, 5, 40, 6])
    ids, segs, obs = map_eval.read_map_lines(f)
    assert ids.dtype == np.int64 and obs.dtype == np.int64
    assert ids.tolist() == [100, 101, 102, 103, 104] and obs.tolist() == [17, 3, 5, 40, 6]
    assert segs.shape == (5, 2, 3) and np.allclose(segs, MAP_W, atol=1e-11)


def test_read_map_lines_header_only_and_blank_lines(tmp_path):
    f = tmp_path / "map_lines.csv"
    f.write_text(HEADER)
    ids, segs, obs = map_eval.read_map_lines(f)
    assert ids.shape == (0,) and segs.shape == (0, 2, 3) and obs.shape == (0,)
    f.write_text(HEADER + "\n  12, 0.1, 0.2, 0.3, 1.1, 0.2, 0.3, 17 \n\n# comment\n")
    ids, segs, obs = map_eval.read_map_lines(f)
    assert ids.tolist() == [12] and segs.tolist() == [[[0.1, 0.2, 0.3], [1.1, 0.2, 0.3]]] and obs.tolist() == [17]


GOOD_ROW = "12,0.1,0.2,0.3,1.1,0.2,0.3,17\n"


@pytest.mark.parametrize("row, pattern", [
    ("13,0.1,0.2,0.3,1.1,0.2,17\n", r"map_lines.csv:3: 7 columns, expected 8 \(id,x0,y0,z0,x1,y1,z1,observations\)"),
    ("13,0.1,0.2,0.3,1.1,0.2,0.3,17,4\n", r"map_lines.csv:3: 9 columns, expected 8"),
    ("13 0.1 0.2 0.3 1.1 0.2 0.3 17\n", r"map_lines.csv:3: 1 columns, expected 8"),
    ("13,0.1,abc,0.3,1.1,0.2,0.3,17\n", r"map_lines.csv:3: 'abc' is not a number"),
    ("13,0.1,,0.3,1.1,0.2,0.3,17\n", r"map_lines.csv:3: '' is not a number"),
    ("13,0.1,nan,0.3,1.1,0.2,0.3,17\n", r"map_lines.csv:3: non-finite coordinate 'nan'"),
    ("x13,0.1,0.2,0.3,1.1,0.2,0.3,17\n", r"map_lines.csv:3: id 'x13' is not an integer"),
    ("13,0.1,0.2,0.3,1.1,0.2,0.3,1.5\n", r"map_lines.csv:3: observations '1.5' is not an integer"),
    ("13,0.1,0.2,0.3,1.1,0.2,0.3,-1\n", r"map_lines.csv:3: negative observation count -1"),
    ("13,0.1,0.2,0.3,0.1,0.2,0.3,17\n", r"map_lines.csv:3: segment of map line 13 has zero length"),
    ("12,0.1,0.2,0.3,1.1,0.2,0.4,17\n", r"map_lines.csv:3: map line id 12 repeated \(first on line 2\)"),
])
def test_read_map_lines_errors_name_file_and_line(tmp_path, row, pattern):
    f = tmp_path / "map_lines.csv"
    f.write_text(HEADER + GOOD_ROW + row)
    with pytest.raises(InputError, match=pattern):
        map_eval.read_map_lines(f)


def test_read_map_lines_missing_or_binary(tmp_path):
    with pytest.raises(InputError, match=r"nothere.csv: no such file"):
        map_eval.read_map_lines(tmp_path / "nothere.csv")
    with pytest.raises(InputError, match=r"is a directory"):
        map_eval.read_map_lines(tmp_path)
    f = tmp_path / "bin.csv"
    f.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(InputError, match=r"bin.csv: not a text file"):
        map_eval.read_map_lines(f)


def test_read_true_lines_errors(tmp_path):
    with pytest.raises(InputError, match=r"lines.csv: no such file \(the true scene lines"):
        map_eval.read_true_lines(tmp_path / "lines.csv")
    f = tmp_path / "lines.csv"
    f.write_text("#id,x0,y0,z0,x1,y1,z1,kind\n0,1,2,3,4,5\n")
    with pytest.raises(InputError, match=r"lines.csv: malformed"):
        map_eval.read_true_lines(f)


# ------------------------------------------------------------------------------------------------------ run folder


def quaternion_wxyz(axis, deg: float) -> np.ndarray:
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return np.array([math.cos(h), *(math.sin(h) * k)])


@pytest.fixture
def run_and_dataset(tmp_path):
    """A run folder in W (trajectory.tum, map_lines.csv) and a simulated dataset in G (ground truth, sim/lines.csv).

    The ground truth is a non-degenerate 3D curve with identity orientations; the estimate is exactly that curve
    expressed in W (so the SE3 alignment must recover T_GT_W). The map lines' observation counts are
    17, 3, 5, 40, 6 (the second is dropped with min_observations 5).
    """
    n = 150
    t_ns = 1_000_000_000 + 50_000_000 * np.arange(n, dtype=np.int64)
    s = np.arange(n) * 0.05
    p_g = np.stack([np.cos(s), np.sin(2 * s), 0.1 * s], axis=1)
    dataset = tmp_path / "dataset"
    gt_dir = dataset / "mav0" / "state_groundtruth_estimate0"
    gt_dir.mkdir(parents=True)
    with open(gt_dir / "data.csv", "w", encoding="utf-8") as f:
        f.write("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
                "v_x, v_y, v_z, bw_x, bw_y, bw_z, ba_x, ba_y, ba_z\n")
        for t, p in zip(t_ns, p_g):
            f.write(",".join([str(t)] + [f"{v:.12f}" for v in p] + ["1", "0", "0", "0"] + ["0"] * 9) + "\n")
    sim = dataset / "sim"
    sim.mkdir()
    with open(sim / "lines.csv", "w", encoding="utf-8") as f:
        f.write("#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],kind\n")
        for i, (a, b) in enumerate(TRUE):
            f.write(f"{i},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},{b[0]:.6f},{b[1]:.6f},{b[2]:.6f},box\n")
    run = tmp_path / "run"
    run.mkdir()
    p_w = p_g @ T_W_GT[:3, :3].T + T_W_GT[:3, 3]
    w, x, y, z = quaternion_wxyz(AXIS, -ANGLE)  # R_W_G (the inverse rotation of T_GT_W) times identity
    with open(run / "trajectory.tum", "w", encoding="utf-8") as f:
        for t, p in zip(t_ns, p_w):
            f.write(f"{t / 1e9:.9f} {p[0]:.12f} {p[1]:.12f} {p[2]:.12f} {x:.15f} {y:.15f} {z:.15f} {w:.15f}\n")
    write_map_lines(run / "map_lines.csv", MAP_W, [17, 3, 5, 40, 6])
    return run, dataset


def test_evaluate_run_map_recovers_the_frame_and_scores(run_and_dataset):
    run, dataset = run_and_dataset
    report = map_eval.evaluate_run_map(run, dataset)
    json.dumps(report)  # JSON-able
    a = report["alignment"]
    assert np.allclose(a["rotation"], T_GT_W[:3, :3], atol=1e-8)
    assert np.allclose(a["translation"], T_GT_W[:3, 3], atol=1e-8)
    assert a["pairs"] == 150 and a["ape_rmse_m"] < 1e-9 and a["scale"] == 1.0 and a["align"] == "se3"
    assert report["lines_total"] == 5 and report["lines_evaluated"] == 4 and report["count"] == 4
    assert report["min_observations"] == 5 and report["within_m"] == 0.05
    assert report["true_lines_total"] == 5 and report["true_lines_associated"] == 4
    kept = [0, 2, 3, 4]  # the 2 deg tilted line has only 3 observations
    dist = np.repeat(np.array(EXPECTED_DIST)[kept], 2)
    assert report["median_angle_deg"] == pytest.approx(0.0, abs=1e-6)
    assert report["median_endpoint_dist_m"] == pytest.approx(np.median(dist), abs=1e-6)
    assert report["p90_endpoint_dist_m"] == pytest.approx(np.percentile(dist, 90), abs=1e-6)
    assert report["frac_within"] == pytest.approx(2 / 4)

    everything = map_eval.evaluate_run_map(run, dataset, min_observations=0, within_m=0.02)
    assert everything["lines_evaluated"] == 5 and everything["frac_within"] == pytest.approx(2 / 5)
    none = map_eval.evaluate_run_map(run, dataset, min_observations=1000)
    assert none["lines_evaluated"] == 0 and none["median_angle_deg"] is None and none["frac_within"] is None
    # the dataset may also be given as its mav0 folder
    assert map_eval.evaluate_run_map(run, dataset / "mav0")["lines_evaluated"] == 4
    # without an endpoint_sigma column a sigma gate keeps nothing
    assert map_eval.evaluate_run_map(run, dataset, max_sigma_m=1.0)["lines_evaluated"] == 0


def test_evaluate_run_map_gates_on_the_endpoint_sigma(run_and_dataset):
    run, dataset = run_and_dataset
    rows = (run / "map_lines.csv").read_text(encoding="utf-8").splitlines()
    sigmas = ["0.01", "0.002", "inf", "0.05", "0.02"]  # observation counts 17, 3, 5, 40, 6
    text = rows[0] + ",t_last [ns],triangulation_angle [deg],endpoint_sigma [m]\n"
    text += "".join(f"{row},123,4.5,{sg}\n" for row, sg in zip(rows[1:], sigmas))
    (run / "map_lines.csv").write_text(text, encoding="utf-8")
    _ids, _segs, _obs, sig = map_eval.read_map_lines(run / "map_lines.csv", with_sigma=True)
    assert sig.tolist() == [0.01, 0.002, math.inf, 0.05, 0.02]
    report = map_eval.evaluate_run_map(run, dataset, max_sigma_m=0.02)
    assert report["lines_evaluated"] == 2 and report["max_sigma_m"] == 0.02  # ids 100 and 104; 101 has 3 observations
    assert map_eval.evaluate_run_map(run, dataset)["lines_evaluated"] == 4  # no gate: as before
    (run / "map_lines.csv").write_text(text.replace(",0.05\n", ",-1\n"), encoding="utf-8")
    with pytest.raises(map_eval.InputError, match=r"map_lines.csv:5: endpoint_sigma '-1' is not a number >= 0"):
        map_eval.read_map_lines(run / "map_lines.csv")


@pytest.mark.parametrize("remove, pattern", [
    ("run/map_lines.csv", r"run/map_lines.csv: no such file"),
    ("run/trajectory.tum", r"run/trajectory.tum: no such file"),
    ("dataset/sim/lines.csv", r"dataset/sim/lines.csv: no such file"),
    ("dataset/mav0/state_groundtruth_estimate0/data.csv", r"state_groundtruth_estimate0/data.csv: no such file"),
])
def test_evaluate_run_map_names_missing_files(run_and_dataset, remove, pattern):
    run, dataset = run_and_dataset
    (run.parent / remove).unlink()
    with pytest.raises(InputError, match=pattern):
        map_eval.evaluate_run_map(run, dataset)


def test_evaluate_run_map_bad_folders_and_malformed_map(run_and_dataset):
    run, dataset = run_and_dataset
    with pytest.raises(InputError, match=r"nothere: not a folder"):
        map_eval.evaluate_run_map(run / "nothere", dataset)
    with pytest.raises(InputError, match=r"nothere: not a folder"):
        map_eval.evaluate_run_map(run, dataset / "nothere")
    with open(run / "map_lines.csv", "a", encoding="utf-8") as f:
        f.write("7,1,2,3\n")
    with pytest.raises(InputError, match=r"map_lines.csv:7: 4 columns, expected 8"):
        map_eval.evaluate_run_map(run, dataset)


# ------------------------------------------------------------------------------------------------------- command


def cli():
    from linnet.cli import cli as command_group

    return command_group


def test_eval_map_command_prints_the_figures_and_writes_json(run_and_dataset, tmp_path):
    run, dataset = run_and_dataset
    out = tmp_path / "out" / "map.json"
    result = CliRunner().invoke(cli(), ["eval-map", str(run), str(dataset), "--json", str(out)])
    assert result.exit_code == 0, result.output
    for text in ("map lines (total)", "evaluated (>= 5 observations)", "median angle [deg]",
                 "median endpoint distance [m]", "90th percentile", "both endpoints within 0.05 m", "0.500",
                 "150 pose pairs"):
        assert text in result.output, text
    report = json.loads(out.read_text())
    assert report["lines_evaluated"] == 4 and report["frac_within"] == pytest.approx(0.5)
    assert np.allclose(report["alignment"]["rotation"], T_GT_W[:3, :3], atol=1e-8)

    result = CliRunner().invoke(cli(), ["eval-map", str(run), str(dataset), "--min-observations", "0",
                                        "--within", "0.02", "--json", str(out)])
    assert result.exit_code == 0, result.output
    assert "both endpoints within 0.02 m" in result.output
    report = json.loads(out.read_text())
    assert report["lines_evaluated"] == 5 and report["min_observations"] == 0 and report["within_m"] == 0.02


def test_eval_map_command_notes_a_map_without_true_segments(run_and_dataset):
    run, dataset = run_and_dataset
    result = CliRunner().invoke(cli(), ["eval-map", str(run), str(dataset)])
    assert result.exit_code == 0 and "score the association, not the map" not in result.output
    # every true segment moved 2 m away (as a scene whose true lines miss the mapped edges)
    lines = dataset / "sim" / "lines.csv"
    rows = lines.read_text(encoding="utf-8").splitlines()
    moved = [rows[0]] + [",".join([r.split(",")[0]] + [str(float(v) + 2.0) for v in r.split(",")[1:7]] +
                                  r.split(",")[7:]) for r in rows[1:] if r and not r.startswith("#")]
    lines.write_text("\n".join(moved) + "\n", encoding="utf-8")
    result = CliRunner().invoke(cli(), ["eval-map", str(run), str(dataset)])
    assert result.exit_code == 0, result.output
    assert "score the association, not the map" in " ".join(result.output.split())


def test_eval_map_command_errors_are_one_line(run_and_dataset):
    run, dataset = run_and_dataset
    (dataset / "sim" / "lines.csv").unlink()
    result = CliRunner().invoke(cli(), ["eval-map", str(run), str(dataset)])
    assert result.exit_code == 1
    assert "sim/lines.csv: no such file" in result.output
    assert len(result.output.strip().splitlines()) == 1
    result = CliRunner().invoke(cli(), ["eval-map", str(run), str(dataset), "--within", "-1"])
    assert result.exit_code == 2 and "--within" in result.output
    assert "eval-map" in CliRunner().invoke(cli(), ["--help"]).output
