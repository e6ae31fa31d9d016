"""Tests of linnet.viewer and ``linnet view``: run-folder loading, PLY maps, aligned ground truth, .rrd output."""
from __future__ import annotations

import json
import sys

import numpy as np
import pytest
from click.testing import CliRunner

from linnet import evaluation as ev
from linnet import viewer
from linnet.cli import cli

PLY = """ply
format ascii 1.0
comment Linnet point-and-line map (world frame, metres)
element vertex 5
property double x
property double y
property double z
property uchar red
property uchar green
property uchar blue
element edge 1
property int vertex1
property int vertex2
end_header
1 2 3 255 0 0
4 5 6 0 255 0
7 8 9 0 0 255
0 0 0 10 20 30
1 0 0 10 20 30
3 4
"""


@pytest.fixture
def run_dir(tmp_path):
    """A run folder: estimate = ground truth rotated 90 deg about z and shifted; map.ply; summary.json -> dataset."""
    n = 200
    t_ns = 1_000_000_000 + 50_000_000 * np.arange(n, dtype=np.int64)
    s = np.arange(n) * 0.05
    gt_p = np.stack([np.cos(s), np.sin(2 * s), 0.1 * s], axis=1)
    gt_q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    dataset = tmp_path / "dataset"
    gt_dir = dataset / "mav0" / "state_groundtruth_estimate0"
    gt_dir.mkdir(parents=True)
    with open(gt_dir / "data.csv", "w") as f:
        f.write("#timestamp,px,py,pz,qw,qx,qy,qz\n")
        for t, p, q in zip(t_ns, gt_p, gt_q):
            f.write(",".join([str(t)] + [f"{v:.12f}" for v in (*p, *q)]) + "\n")
    est_p = np.stack([-gt_p[:, 1], gt_p[:, 0], gt_p[:, 2]], axis=1) + [3.0, -1.0, 0.5]
    c = np.sqrt(0.5)
    run = tmp_path / "run"
    run.mkdir()
    with open(run / "trajectory.tum", "w") as f:
        for t, p in zip(t_ns, est_p):
            f.write(f"{t / 1e9:.9f} {p[0]:.12f} {p[1]:.12f} {p[2]:.12f} 0 0 {c:.15f} {c:.15f}\n")
    (run / "map.ply").write_text(PLY)
    (run / "summary.json").write_text(json.dumps({"dataset": str(dataset)}))
    return run, est_p


def test_read_ply_points_and_segments(tmp_path):
    f = tmp_path / "m.ply"
    f.write_text(PLY)
    m = viewer.read_ply(f)
    assert m.points.tolist() == [[1, 2, 3], [4, 5, 6], [7, 8, 9]]
    assert m.point_colors.tolist() == [[255, 0, 0], [0, 255, 0], [0, 0, 255]]
    assert m.segments.tolist() == [[[0, 0, 0], [1, 0, 0]]]
    assert m.segment_colors.tolist() == [[10, 20, 30]]


@pytest.mark.parametrize("text, pattern", [
    ("plyx\n", r"m.ply:1: not a PLY file"),
    (PLY.replace("ascii", "binary_little_endian"), r"m.ply:2: only ASCII PLY"),
    (PLY.replace("4 5 6 0 255 0", "4 5 0 255 0"), r"m.ply:16: 5 values, element 'vertex' has 6"),
    (PLY.replace("3 4\n", ""), r"truncated, element 'edge' has 0 of 1 rows"),
    (PLY.replace("3 4\n", "3 9\n"), r"edge refers to a vertex outside 0..4"),
])
def test_read_ply_errors(tmp_path, text, pattern):
    f = tmp_path / "m.ply"
    f.write_text(text)
    with pytest.raises(ev.InputError, match=pattern):
        viewer.read_ply(f)


def test_load_run_aligns_ground_truth_into_the_estimate_frame(run_dir):
    run, est_p = run_dir
    view = viewer.load_run(run)
    assert len(view.estimate) == 200
    assert view.ground_truth is not None and view.ape_rmse_m < 1e-8
    assert np.allclose(view.ground_truth.positions, est_p, atol=1e-8)
    # the orientations move with the positions: identity gt -> the estimate's 90 deg yaw
    assert np.allclose(np.abs(view.ground_truth.quaternions_wxyz), [np.sqrt(0.5), 0, 0, np.sqrt(0.5)], atol=1e-8)
    assert len(view.map.points) == 3 and len(view.map.segments) == 1
    assert view.notes == []


def test_load_run_without_ground_truth_or_map(run_dir):
    run, _ = run_dir
    (run / "summary.json").unlink()
    (run / "map.ply").unlink()
    view = viewer.load_run(run)
    assert view.ground_truth is None and view.map is None
    assert any("no ground truth" in n for n in view.notes) and "no map.ply" in view.notes
    with pytest.raises(ev.InputError, match="no trajectory.tum or trajectory.csv"):
        viewer.load_run(run / "..")


MAP_LINES = "#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],observations\n7,0,0,0,1,0,0,12\n9,0,1,0,0,1,2,3\n"


def test_load_run_takes_segments_from_map_lines_csv_when_map_ply_has_no_edges(run_dir):
    run, _ = run_dir
    (run / "map_lines.csv").write_text(MAP_LINES)
    assert len(viewer.load_run(run).map.segments) == 1  # map.ply's edge wins
    (run / "map.ply").write_text(PLY.replace("element edge 1\n", "element edge 0\n").replace("3 4\n", ""))
    view = viewer.load_run(run)
    assert len(view.map.points) == 5
    assert view.map.segments.tolist() == [[[0, 0, 0], [1, 0, 0]], [[0, 1, 0], [0, 1, 2]]]
    assert view.map.segment_colors is None
    assert view.notes == ["map lines read from map_lines.csv (map.ply has none)"]
    (run / "map.ply").unlink()
    view = viewer.load_run(run)
    assert len(view.map.points) == 0 and len(view.map.segments) == 2
    assert view.notes == ["no map.ply", "map lines read from map_lines.csv (map.ply has none)"]
    (run / "map_lines.csv").write_text(MAP_LINES + "10,1,2\n")
    with pytest.raises(ev.InputError, match=r"map_lines.csv:4: 3 columns, expected 8"):
        viewer.load_run(run)


def test_view_saves_a_recording(run_dir, tmp_path):
    pytest.importorskip("rerun")
    run, _ = run_dir
    out = tmp_path / "rec" / "run.rrd"
    result = CliRunner().invoke(cli, ["view", str(run), "--save", str(out)])
    assert result.exit_code == 0, result.output
    assert "200 poses, 3 map points, 1 map lines, APE RMSE 0.0000 m" in result.output
    assert out.stat().st_size > 1000
    assert out.read_bytes()[:4] == b"RRF2"  # rerun's file magic


def test_view_without_rerun_says_how_to_install(run_dir, tmp_path, monkeypatch):
    run, _ = run_dir
    monkeypatch.setitem(sys.modules, "rerun", None)  # makes `import rerun` raise ImportError
    result = CliRunner().invoke(cli, ["view", str(run), "--save", str(tmp_path / "x.rrd")])
    assert result.exit_code == 1
    assert "pip install 'linnet[viewer]'" in result.output


def test_view_help_and_bad_folder(tmp_path):
    result = CliRunner().invoke(cli, ["view", "--help"])
    assert result.exit_code == 0 and "--save" in result.output
    empty = tmp_path / "empty"
    empty.mkdir()
    result = CliRunner().invoke(cli, ["view", str(empty)])
    assert result.exit_code == 1 and "no trajectory.tum" in result.output
