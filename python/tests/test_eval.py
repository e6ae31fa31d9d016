"""Tests of linnet.evaluation and linnet.plots: peer cross-check, synthetic offsets, formats, errors, plots."""
from __future__ import annotations

import numpy as np
import pytest

from linnet import evaluation as ev
from linnet import plots

CROSSCHECK = "eval_crosscheck/vinsmono_MH_01"


# ------------------------------------------------------------------------------------------------------ helpers


def quat_mul(a, b):
    """Hamilton product of (N, 4) or (4,) quaternions, order w, x, y, z."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, dtype=float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, dtype=float), -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def quat_from_axis_angle(axis, angle):
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    return np.concatenate([[np.cos(angle / 2)], np.sin(angle / 2) * axis])


def rot_of_quat(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def helix(n=400, rate_hz=20.0, t0_ns=1_000_000_000_000):
    """A 3D helix with yaw following the path and a pitch wobble: (t_ns, p, q_wxyz)."""
    dt_ns = int(round(1e9 / rate_hz))
    t_ns = t0_ns + dt_ns * np.arange(n, dtype=np.int64)
    s = np.arange(n) / rate_hz
    p = np.stack([2.0 * np.cos(0.3 * s), 1.5 * np.sin(0.3 * s), 0.05 * s + 0.2 * np.sin(1.1 * s)], axis=1)
    q_yaw = np.stack([quat_from_axis_angle([0, 0, 1], 0.3 * si + np.pi / 2) for si in s])
    q_pitch = np.stack([quat_from_axis_angle([0, 1, 0], 0.2 * np.sin(0.7 * si)) for si in s])
    return t_ns, p, quat_mul(q_yaw, q_pitch)


def transformed(p, q, q_off, t_off, scale=1.0):
    """Apply p -> s R p + t and q -> q_off q (a similarity of the world frame)."""
    r = rot_of_quat(q_off)
    return scale * p @ r.T + t_off, quat_mul(np.broadcast_to(q_off, q.shape), q)


def write_tum(path, t_ns, p, q_wxyz):
    with open(path, "w") as f:
        f.write("# t x y z qx qy qz qw\n")
        for t, pi, qi in zip(t_ns, p, q_wxyz):
            sec, ns = divmod(int(t), 1_000_000_000)
            f.write(f"{sec}.{ns:09d} {pi[0]:.12f} {pi[1]:.12f} {pi[2]:.12f} "
                    f"{qi[1]:.12f} {qi[2]:.12f} {qi[3]:.12f} {qi[0]:.12f}\n")
    return path


def write_euroc(path, t_ns, p, q_wxyz, columns=17):
    with open(path, "w") as f:
        f.write("#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z []"
                + (",v_x,v_y,v_z,bw_x,bw_y,bw_z,ba_x,ba_y,ba_z" if columns == 17 else "") + "\n")
        for t, pi, qi in zip(t_ns, p, q_wxyz):
            row = [str(int(t))] + [f"{v:.12f}" for v in (*pi, *qi)]
            if columns == 17:
                row += ["0.1"] * 9
            f.write(",".join(row) + "\n")
    return path


# ------------------------------------------------------------------------------------------- peer cross-check


def test_crosscheck_vinsmono_mh01_matches_evo_ape(shared_data):
    """evo_ape tum ground_truth.tum vins_tum.txt -va --t_max_diff 0.1 --pose_relation trans_part (data README)."""
    folder = shared_data(CROSSCHECK)
    res = ev.ape(folder / "vins_tum.txt", folder / "ground_truth.tum", align="se3", t_max_diff=0.1,
                 pose_relation="trans_part")
    assert res.pairs == 771
    assert res.rmse == pytest.approx(0.1403045640930528, abs=1e-5)
    assert res.mean == pytest.approx(0.124233, abs=1e-5)
    assert res.median == pytest.approx(0.116256, abs=1e-5)
    assert res.max == pytest.approx(0.349619, abs=1e-5)
    assert res.unit == "m"
    assert res.scale == 1.0
    assert len(res.estimate) == len(res.reference) == res.errors.shape[0] == res.t_ns.shape[0] == 771
    # the rotation of the SE3 alignment is a rotation
    assert np.allclose(res.rotation @ res.rotation.T, np.eye(3), atol=1e-9)
    assert np.linalg.det(res.rotation) == pytest.approx(1.0, abs=1e-9)


# ----------------------------------------------------------------------------------------- synthetic offsets


def test_rigid_offset_vanishes_after_se3_and_is_measured_without_alignment():
    t, p, q = helix()
    gt = ev.trajectory_from_arrays(t, p, q, name="gt")
    q_off = quat_from_axis_angle([0.2, -0.5, 1.0], 0.8)
    t_off = np.array([1.0, -2.0, 0.5])
    p2, q2 = transformed(p, q, q_off, t_off)
    est = ev.trajectory_from_arrays(t, p2, q2, name="est")

    for relation in ("trans_part", "full", "angle_deg"):
        res = ev.ape(est, gt, align="se3", pose_relation=relation)
        assert res.pairs == len(t)
        assert res.rmse < 1e-8, relation
    res = ev.ape(est, gt, align="sim3")
    assert res.rmse < 1e-8
    assert res.scale == pytest.approx(1.0, abs=1e-9)
    # the aligned estimate lands on the ground truth, the alignment is the inverse offset
    assert np.allclose(res.estimate.positions, p, atol=1e-8)
    assert np.allclose(res.rotation, rot_of_quat(q_off).T, atol=1e-9)

    none = ev.ape(est, gt, align="none")
    expected = np.linalg.norm(p2 - p, axis=1)
    assert none.rmse == pytest.approx(float(np.sqrt(np.mean(expected ** 2))), rel=1e-12)
    assert none.max == pytest.approx(float(expected.max()), rel=1e-12)
    assert none.min == pytest.approx(float(expected.min()), rel=1e-12)
    assert np.allclose(none.errors, expected, rtol=1e-12)


def test_similarity_offset_needs_sim3():
    t, p, q = helix()
    gt = ev.trajectory_from_arrays(t, p, q)
    q_off = quat_from_axis_angle([1.0, 1.0, 0.0], -0.4)
    p2, q2 = transformed(p, q, q_off, np.array([0.3, 0.2, -0.1]), scale=2.5)
    est = ev.trajectory_from_arrays(t, p2, q2)
    sim3 = ev.ape(est, gt, align="sim3")
    assert sim3.rmse < 1e-8
    assert sim3.scale == pytest.approx(1.0 / 2.5, rel=1e-9)
    se3 = ev.ape(est, gt, align="se3")
    assert se3.rmse > 0.5  # a scale error of 2.5 on a ~2 m helix cannot be explained by a rigid motion
    # RPE is scale-sensitive too: ~0 only after sim3
    assert ev.rpe(est, gt, delta=1.0, align="sim3").rmse < 1e-8
    assert ev.rpe(est, gt, delta=1.0, align="none").rmse > 0.5


def test_constant_position_error_and_association_tolerance():
    """A 5 cm offset along x with time jitter inside t_max_diff: APE 0.05 m without alignment, pairs as expected."""
    t, p, q = helix(n=200)
    gt = ev.trajectory_from_arrays(t, p, q)
    jitter = np.where(np.arange(len(t)) % 2 == 0, 3_000_000, -2_000_000)  # +3 ms / -2 ms
    est = ev.trajectory_from_arrays(t + jitter, p + [0.05, 0.0, 0.0], q)
    res = ev.ape(est, gt, align="none", t_max_diff=0.01)
    assert res.pairs == 200
    assert res.rmse == pytest.approx(0.05, abs=1e-12)
    assert np.array_equal(res.t_ns, t + jitter)  # time stamps of the estimate, exact ns
    assert np.array_equal(res.reference.t_ns, t)
    # with a tighter tolerance only the -2 ms poses associate
    tight = ev.ape(est, gt, align="none", t_max_diff=0.0025)
    assert tight.pairs == 100


def test_rpe_on_rigid_offset_and_frames_delta():
    t, p, q = helix()
    gt = ev.trajectory_from_arrays(t, p, q)
    p2, q2 = transformed(p, q, quat_from_axis_angle([0, 0, 1], 1.0), np.array([5.0, 0.0, 0.0]))
    est = ev.trajectory_from_arrays(t, p2, q2)
    for align in ("se3", "none"):
        res = ev.rpe(est, gt, delta=1.0, delta_unit="m", align=align)
        assert res.rmse < 1e-8
        assert res.pairs > 5
        assert res.metric == "rpe" and res.delta == 1.0 and res.delta_unit == "m"
        assert res.t_ns.shape == res.errors.shape
    frames = ev.rpe(est, gt, delta=10, delta_unit="frames")
    assert frames.pairs == (len(t) - 1) // 10
    # a drifting estimate: position error growing linearly along x, 1 mm per frame
    drift = ev.trajectory_from_arrays(t, p + np.outer(np.arange(len(t)) * 1e-3, [1, 0, 0]), q)
    res = ev.rpe(drift, gt, delta=10, delta_unit="frames", align="none")
    assert res.rmse == pytest.approx(0.01, rel=1e-9)


def test_rpe_delta_longer_than_path_is_an_input_error():
    t, p, q = helix(n=20)
    gt = ev.trajectory_from_arrays(t, p, q)
    with pytest.raises(ev.InputError, match=r"travels .* m over the estimate.s span, not more than the RPE delta 100 m"):
        ev.rpe(gt, gt, delta=100.0)


def test_path_length_of_a_square():
    t = np.arange(5, dtype=np.int64) * 1_000_000_000
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0, 0, 0]], dtype=float)
    q = np.tile([1.0, 0, 0, 0], (5, 1))
    assert ev.path_length(ev.trajectory_from_arrays(t, p, q)) == pytest.approx(4.0)
    assert ev.path_length(ev.trajectory_from_arrays(t[:1], p[:1], q[:1])) == 0.0


# ------------------------------------------------------------------------------------------------ formats


def test_tum_and_euroc_files_load_to_the_same_trajectory(tmp_path):
    t, p, q = helix(n=50)
    tum = write_tum(tmp_path / "a.txt", t, p, q)
    e8 = write_euroc(tmp_path / "a8.csv", t, p, q, columns=8)
    e17 = write_euroc(tmp_path / "a17.csv", t, p, q, columns=17)
    assert ev.detect_format(tum) == "tum"
    assert ev.detect_format(e8) == "euroc"
    assert ev.detect_format(e17) == "euroc"
    for path in (tum, e8, e17):
        traj = ev.load_trajectory(path)
        assert np.array_equal(traj.t_ns, t)
        assert np.allclose(traj.positions, p, atol=1e-11)
        assert np.allclose(traj.quaternions_wxyz, q, atol=1e-11)
        assert traj.name == str(path)
    # the extension does not matter, the content does
    (tmp_path / "tum.csv").write_text(tum.read_text())
    assert ev.detect_format(tmp_path / "tum.csv") == "tum"


def test_tum_time_stamps_are_read_exactly_to_the_nanosecond(tmp_path):
    f = tmp_path / "t.tum"
    f.write_text("1403636589.863555431 0 0 0 0 0 0 1\n1.403636589963555574e+09 1 0 0 0 0 0 1\n")
    traj = ev.load_trajectory(f)
    assert traj.t_ns.tolist() == [1403636589863555431, 1403636589963555574]
    assert traj.quaternions_wxyz[0].tolist() == [1.0, 0.0, 0.0, 0.0]


def test_quaternion_order_of_each_format(tmp_path):
    tum = tmp_path / "q.tum"
    tum.write_text("0.0 0 0 0 0.1 0.2 0.3 0.9\n")  # x y z w
    csv = tmp_path / "q.csv"
    csv.write_text("0,0,0,0,0.9,0.1,0.2,0.3\n")  # w x y z
    a, b = ev.load_trajectory(tum), ev.load_trajectory(csv)
    assert np.allclose(a.quaternions_wxyz, b.quaternions_wxyz)
    assert a.quaternions_wxyz[0, 0] == pytest.approx(0.9 / np.linalg.norm([0.9, 0.1, 0.2, 0.3]))


# ------------------------------------------------------------------------------------------------- errors


def test_missing_file(tmp_path):
    with pytest.raises(ev.InputError, match="nope.txt: no such file"):
        ev.load_trajectory(tmp_path / "nope.txt")


@pytest.mark.parametrize("text", ["", "\n\n", "# only a header\n# and a comment\n"])
def test_empty_file(tmp_path, text):
    f = tmp_path / "empty.txt"
    f.write_text(text)
    with pytest.raises(ev.InputError, match=r"empty.txt: no poses"):
        ev.load_trajectory(f)


@pytest.mark.parametrize("bad_line, pattern", [
    ("3.0 1 2 3 0 0 0", r"bad.txt:4: 7 fields"),
    ("3.0 1 2 x 0 0 0 1", r"bad.txt:4: 'x' is not a number"),
    ("abc 1 2 3 0 0 0 1", r"bad.txt:4: bad time stamp 'abc'"),
    ("3.0 1 2 3 0 0 0 0", r"bad.txt:4: zero quaternion"),
    ("3.0 1 2 nan 0 0 0 1", r"bad.txt:4: non-finite"),
    ("1.5 1 2 3 0 0 0 1", r"bad.txt:4: time stamp 1500000000 ns is not after .* \(line 3\)"),
    ("3,1,2,3,1,0,0,0", r"bad.txt:4: 1 fields, expected 8 \(TUM"),  # a csv line in a TUM file
])
def test_malformed_tum_line_is_named(tmp_path, bad_line, pattern):
    f = tmp_path / "bad.txt"
    f.write_text("# header\n1.0 0 0 0 0 0 0 1\n2.0 0 0 0 0 0 0 1\n" + bad_line + "\n")
    with pytest.raises(ev.InputError, match=pattern):
        ev.load_trajectory(f)


def test_malformed_euroc_lines_are_named(tmp_path):
    f = tmp_path / "bad.csv"
    f.write_text("#t,...\n1,0,0,0,1,0,0,0\n2,0,0,0,1,0,0\n")
    with pytest.raises(ev.InputError, match=r"bad.csv:3: 7 columns, expected 8"):
        ev.load_trajectory(f)
    f.write_text("1,0,0,0,1,0,0,0,0,0\n")
    with pytest.raises(ev.InputError, match=r"bad.csv:1: comma-separated line with 10 columns"):
        ev.load_trajectory(f)


def test_no_overlapping_time_stamps():
    t, p, q = helix(n=50)
    gt = ev.trajectory_from_arrays(t, p, q, name="gt.txt")
    est = ev.trajectory_from_arrays(t + 3_600_000_000_000, p, q, name="est.txt")
    with pytest.raises(ev.InputError, match=r"no time stamps of est.txt .* and gt.txt .* within 0.01 s"):
        ev.ape(est, gt)


def test_array_validation():
    t, p, q = helix(n=10)
    with pytest.raises(ev.InputError, match=r"positions must have shape \(10, 3\)"):
        ev.trajectory_from_arrays(t, p[:, :2], q)
    with pytest.raises(ev.InputError, match="strictly increasing, pose 5"):
        ev.trajectory_from_arrays(np.r_[t[:5], t[4], t[6:]], p, q)
    with pytest.raises(ev.InputError, match="zero quaternion in pose 2"):
        q2 = q.copy()
        q2[2] = 0
        ev.trajectory_from_arrays(t, p, q2)
    with pytest.raises(ValueError, match="align must be one of"):
        ev.ape(ev.trajectory_from_arrays(t, p, q), ev.trajectory_from_arrays(t, p, q), align="rigid")
    with pytest.raises(ev.InputError, match="at least 3 associated poses"):
        ev.ape(ev.trajectory_from_arrays(t[:2], p[:2], q[:2]), ev.trajectory_from_arrays(t, p, q))


# -------------------------------------------------------------------------------------------------- plots


def test_plots_are_written_and_deterministic(tmp_path):
    t, p, q = helix(n=120)
    gt = ev.trajectory_from_arrays(t, p, q, name="gt")
    rng = np.random.default_rng(7)
    est = ev.trajectory_from_arrays(t, p + rng.normal(0, 0.02, p.shape), q, name="est")
    a = ev.ape(est, gt)
    r = ev.rpe(est, gt, delta=0.5)
    first = plots.plot_all(a, tmp_path / "one", rpe_result=r, gt_full=gt)
    second = plots.plot_all(a, tmp_path / "two", rpe_result=r, gt_full=gt)
    names = sorted(x.name for x in first)
    assert names == ["ape_over_time.png", "rpe_over_time.png", "top_view.png", "xyz.png"]
    for f1, f2 in zip(first, second):
        data = f1.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        assert len(data) > 10_000
        assert data == f2.read_bytes(), f1.name
    # uncoloured top view and the plot_ape shortcut
    plots.plot_top_view(a, tmp_path / "plain.png", color_by_error=False)
    assert (tmp_path / "plain.png").stat().st_size > 10_000
    assert [x.name for x in plots.plot_ape(a, tmp_path / "three")] == ["top_view.png", "ape_over_time.png", "xyz.png"]


def test_degenerate_alignment_is_an_input_error():
    """On a straight line the rotation about the line is unobservable: a clear error, not a silent result."""
    t = np.arange(20, dtype=np.int64) * 100_000_000
    p = np.outer(np.arange(20) * 0.1, [1.0, 0.0, 0.0])
    q = np.tile([1.0, 0, 0, 0], (20, 1))
    line = ev.trajectory_from_arrays(t, p, q)
    with pytest.raises(ev.InputError, match="se3 alignment failed"):
        ev.ape(line, line, align="se3")
    assert ev.ape(line, line, align="none").rmse == 0.0


def test_plot_lines_break_at_time_gaps():
    t = np.array([0.0, 0.1, 0.2, 5.0, 5.1, 5.2])
    t2, y2 = plots._break_gaps(t, t * 2)
    assert np.isnan(t2[3]) and np.isnan(y2[3]) and t2.shape == (7,)
    assert np.array_equal(t2[[0, 1, 2, 4, 5, 6]], t)
    t3, _ = plots._break_gaps(t[:3], t[:3])
    assert np.array_equal(t3, t[:3])
