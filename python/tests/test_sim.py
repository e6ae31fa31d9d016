"""Tests of the trajectory-replay simulator (issue 3): IMU consistency with the ground truth, projection of the
scene's ground-truth geometry onto the rendered images, stereo extrinsics, EuRoC layout, determinism."""
from __future__ import annotations

import hashlib
import os
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml

from linnet.sim import InputError, build_scene, builtin_loop, load_trajectory
from linnet.sim import writer
from linnet.sim.groundtruth import SequenceTruth, project_points, read_csv_ns, sample_segments
from linnet.sim.rig import EUROC_CAM0, EUROC_CAM1, project
from linnet.sim.rotations import quat_mul, quat_to_matrix
from linnet.sim.simulator import CAMERA_EVERY, prepare, simulate
from linnet.sim.trajectory import GRAVITY_W, SplineTrajectory

SHARED = Path(os.environ.get("LINNET_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))
IN_CI = os.environ.get("CI") == "true"

# The short replay most tests look at: 3 s of the built-in loop in motion, low-texture room, noise-free IMU.
REPLAY = dict(trajectory="builtin:loop", scene="lowtex", seed=3, start=4.0, duration=3.0, imu_noise="none")


def need_shared(path: Path):
    if not path.exists():
        if IN_CI:
            pytest.fail(f"shared data missing: {path}")
        pytest.skip(f"shared data missing: {path}")


@pytest.fixture(scope="module")
def replay(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim") / "lowtex"
    summary = simulate(out_dir=out, **REPLAY)
    return out, summary


# ------------------------------------------------------------------------------------------------ IMU and trajectory
def integrate_rk4(t_ns, gyr, acc, p0, q0, v0):
    """Classical RK4 on (q, v, p) with step 2 dt, using the IMU samples at t, t + dt, t + 2 dt (midpoint = middle
    sample). Returns positions and quaternions at every other sample."""
    def deriv(q, v, w, f):
        dq = 0.5 * quat_mul(q, np.array([0.0, *w]))
        return dq, quat_to_matrix(q) @ f + GRAVITY_W, v

    h = (t_ns[2] - t_ns[0]) * 1e-9
    q, v, p = q0.copy(), v0.copy(), p0.copy()
    ps, qs = [p.copy()], [q.copy()]
    for k in range(0, t_ns.size - 2, 2):
        w0, wm, w1 = gyr[k], gyr[k + 1], gyr[k + 2]
        f0, fm, f1 = acc[k], acc[k + 1], acc[k + 2]
        k1 = deriv(q, v, w0, f0)
        k2 = deriv(q + 0.5 * h * k1[0], v + 0.5 * h * k1[1], wm, fm)
        k3 = deriv(q + 0.5 * h * k2[0], v + 0.5 * h * k2[1], wm, fm)
        k4 = deriv(q + h * k3[0], v + h * k3[1], w1, f1)
        q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        q /= np.linalg.norm(q)
        p = p + h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
        v = v + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        ps.append(p.copy())
        qs.append(q.copy())
    return np.array(ps), np.array(qs)


def check_imu_reproduces_groundtruth(imu_csv: Path, gt_csv: Path, seconds: float):
    t, imu = read_csv_ns(imu_csv)
    tg, gt = read_csv_ns(gt_csv)
    n = int(round(seconds * 200)) + 1
    assert t.size >= n and np.array_equal(t[:n], tg[:n])
    ps, qs = integrate_rk4(t[:n], imu[:n, 0:3], imu[:n, 3:6], gt[0, 0:3], gt[0, 3:7], gt[0, 7:10])
    ref_p, ref_q = gt[:n:2, 0:3], gt[:n:2, 3:7]
    drift = np.linalg.norm(ps - ref_p, axis=1)
    dq = quat_mul(qs * np.array([1, -1, -1, -1]), ref_q)
    ang = np.degrees(2 * np.arctan2(np.linalg.norm(dq[:, 1:], axis=1), np.abs(dq[:, 0])))
    travelled = np.linalg.norm(np.diff(ref_p, axis=0), axis=1).sum()
    print(f"{imu_csv.parent.parent.parent.name}: {seconds:.0f} s, {travelled:.1f} m travelled: position drift "
          f"{drift.max() * 1000:.4f} mm max, rotation {ang.max():.2e} deg max")
    assert drift.max() < 1e-3
    assert ang.max() < 0.01
    return drift.max()


def test_noise_free_imu_integrates_to_the_groundtruth_over_10_s(tmp_path):
    rp = prepare("builtin:loop", "lowtex", seed=1, start=2.0, duration=10.0, imu_noise="none")
    writer.write_imu(tmp_path / "mav0", rp.imu, rp.noise)
    writer.write_groundtruth(tmp_path / "mav0", rp.imu_t, rp.state, rp.imu.bias_gyr, rp.imu.bias_acc)
    check_imu_reproduces_groundtruth(tmp_path / "mav0" / "imu0" / "data.csv",
                                     tmp_path / "mav0" / "state_groundtruth_estimate0" / "data.csv", 10.0)


def test_noise_free_imu_of_a_real_euroc_motion(tmp_path):
    gt = SHARED / "euroc_groundtruth" / "V1_02_medium.txt"
    need_shared(gt)
    rp = prepare(str(gt), "room", seed=1, start=20.0, duration=10.0, imu_noise="none")
    writer.write_imu(tmp_path / "mav0", rp.imu, rp.noise)
    writer.write_groundtruth(tmp_path / "mav0", rp.imu_t, rp.state, rp.imu.bias_gyr, rp.imu.bias_acc)
    check_imu_reproduces_groundtruth(tmp_path / "mav0" / "imu0" / "data.csv",
                                     tmp_path / "mav0" / "state_groundtruth_estimate0" / "data.csv", 10.0)
    assert rp.fit["position_rms_m"] < 2e-3 and rp.fit["rotation_rms_deg"] < 0.2


def test_written_replay_imu_matches_its_groundtruth(replay):
    out, _ = replay
    check_imu_reproduces_groundtruth(out / "mav0" / "imu0" / "data.csv",
                                     out / "mav0" / "state_groundtruth_estimate0" / "data.csv", 2.9)


def test_spline_derivatives_match_finite_differences():
    s = builtin_loop()
    spline, fit = SplineTrajectory.fit(s, int(s.t_ns[0]), int(s.t_ns[-1]))
    assert fit["position_rms_m"] < 1e-5 and fit["rotation_rms_deg"] < 1e-3
    t = s.t_ns[0] + np.arange(1000, 5000, 397) * 5_000_000 + 1234567
    h = 1000  # ns
    a, b, c = spline.evaluate(t - h), spline.evaluate(t), spline.evaluate(t + h)
    np.testing.assert_allclose(b.v, (c.p - a.p) / (2 * h * 1e-9), atol=1e-6)
    np.testing.assert_allclose(b.a, (c.v - a.v) / (2 * h * 1e-9), atol=1e-5)
    dq = quat_mul(b.q * np.array([1, -1, -1, -1]), c.q - a.q) / (2 * h * 1e-9)
    np.testing.assert_allclose(b.omega_B, 2 * dq[:, 1:], atol=1e-6)


def test_builtin_loop_is_a_realistic_indoor_flight():
    s = builtin_loop()
    spline, _ = SplineTrajectory.fit(s, int(s.t_ns[0]), int(s.t_ns[-1]))
    st = spline.evaluate(s.t_ns)
    speed = np.linalg.norm(st.v, axis=1)
    moving = s.t_ns - s.t_ns[0] > 4e9
    assert abs(s.duration - 30.0) < 1e-6
    assert speed[: 150].max() < 1e-3                        # at rest for the first 0.75 s
    assert 0.5 <= speed[moving].min() and speed[moving].max() <= 1.5
    up_B = np.einsum("nji,j->ni", st.R, [0, 0, 1.0])      # world up in the body frame (body x is up on the MAV)
    tilt = np.degrees(np.arccos(np.clip(up_B[:, 0], -1, 1)))
    assert 3.0 < tilt.max() < 20.0                         # some roll / pitch, never aerobatics
    yaw_rate = np.abs(st.omega_B[:, 0])
    assert yaw_rate.max() > 0.3                            # real turns
    assert st.p[:, 2].min() > 0.5 and np.ptp(st.p[:, 2]) > 0.3


# ----------------------------------------------------------------------------------------------------- EuRoC layout
def load_yaml(path: Path) -> dict:
    text = path.read_text()
    assert text.startswith("%YAML:1.0")
    return yaml.safe_load(text.split("\n", 1)[1])


def test_outputs_follow_the_euroc_asl_layout(replay):
    out, summary = replay
    mav0 = out / "mav0"
    assert (mav0 / "body.yaml").is_file()
    t_imu, imu = read_csv_ns(mav0 / "imu0" / "data.csv")
    assert imu.shape[1] == 6 and np.all(np.diff(t_imu) == 5_000_000)
    assert (mav0 / "imu0" / "data.csv").read_text().startswith("#timestamp [ns],w_RS_S_x")  # gyro first
    imu_yaml = load_yaml(mav0 / "imu0" / "sensor.yaml")
    assert imu_yaml["rate_hz"] == 200 and imu_yaml["gyroscope_noise_density"] > 0.0  # nominal: readers need > 0
    assert "NOTE: the measurements were simulated with" in (mav0 / "imu0" / "sensor.yaml").read_text()
    t_gt, gt = read_csv_ns(mav0 / "state_groundtruth_estimate0" / "data.csv")
    assert gt.shape[1] == 16 and np.array_equal(t_gt, t_imu)
    np.testing.assert_allclose(np.linalg.norm(gt[:, 3:7], axis=1), 1.0, atol=1e-9)
    for cam, spec in ((0, EUROC_CAM0), (1, EUROC_CAM1)):
        d = mav0 / f"cam{cam}"
        rows = [l.split(",") for l in (d / "data.csv").read_text().splitlines() if not l.startswith("#")]
        t_cam = np.array([int(r[0]) for r in rows])
        assert np.array_equal(t_cam, t_imu[::CAMERA_EVERY])       # 20 Hz on the IMU clock
        assert len(rows) == summary["frames"]
        for r in rows[:: max(1, len(rows) // 5)]:
            img = cv2.imread(str(d / "data" / r[1]), cv2.IMREAD_UNCHANGED)
            assert img.dtype == np.uint8 and img.shape == (480, 752)
            assert 20 < img.mean() < 230 and img.std() > 5
        y = load_yaml(d / "sensor.yaml")
        assert y["resolution"] == [752, 480] and y["distortion_model"] == "radial-tangential"
        np.testing.assert_allclose(y["intrinsics"], spec.intrinsics)
        np.testing.assert_allclose(np.array(y["T_BS"]["data"]).reshape(4, 4), spec.T_B_C)
    for name in ("lines.csv", "points.csv", "README.md", "info.yaml"):
        assert (out / "sim" / name).is_file()
    truth = SequenceTruth.load(out)
    assert len(truth.lines) > 100 and len(truth.points) > 50


def test_linnet_euroc_reader_reads_the_output(replay):
    """The C++ EuRoC reader (io layer) takes the calibration from the written sensor.yaml files and runs the first
    frames of the sequence (images, IMU and ground truth)."""
    out, summary = replay
    core = pytest.importorskip("linnet._linnet")
    cfg = core.Config.for_euroc(str(out))
    text = cfg.to_yaml()
    assert "458.654" in text and "457.587" in text        # cam0 and cam1 intrinsics from the written sensor.yaml
    run = core.run_euroc(str(out), cfg, 5, 0.0, None)
    assert run.frames == 5


# ----------------------------------------------------------------------------------------- images vs ground truth
def edge_offsets(img, px, normals, half=2.0, step=0.1):
    """Signed distance (px) along the normal from each point to the strongest intensity step, and its strength."""
    sm = cv2.GaussianBlur(img.astype(np.float32), (0, 0), 1.0)
    offs = np.arange(-half, half + step / 2, step)
    xs = (px[:, 0:1] + normals[:, 0:1] * offs).astype(np.float32)
    ys = (px[:, 1:2] + normals[:, 1:2] * offs).astype(np.float32)
    g = np.abs(np.gradient(cv2.remap(sm, xs, ys, cv2.INTER_LINEAR), step, axis=1))
    k = np.clip(np.argmax(g, axis=1), 1, offs.size - 2)
    r = np.arange(k.size)
    a, b, c = g[r, k - 1], g[r, k], g[r, k + 1]
    den = a - 2 * b + c
    delta = np.where(np.abs(den) > 1e-9, 0.5 * (a - c) / np.where(np.abs(den) > 1e-9, den, 1.0), 0.0)
    return offs[k] + delta * step, b


# Edges that are isolated steps between two surfaces (frame bars, skirting tops and grout bands have a second edge
# within a pixel or two from some views, which moves a gradient peak without any rendering error).
ISOLATED_EDGES = ("box", "pipe", "wall_corner", "wall_ceiling", "pillar")
CORNERS = ("box", "room_corner", "pillar", "pipe")


def test_ground_truth_lines_and_points_land_on_rendered_edges_and_corners(replay):
    out, _ = replay
    truth = SequenceTruth.load(out)
    scene = prepare(**REPLAY).scene.to_native()
    lines_sel = np.array([k in ISOLATED_EDGES for k in truth.line_kinds])
    pts_sel = np.array([k in CORNERS for k in truth.point_kinds])
    line_off, corner_err, disp = [], [], []
    for cam in (0, 1):
        renderer = truth.cameras[cam].renderer()
        for t in truth.frames[::6]:
            T = truth.camera_pose(int(t), cam)
            depth = renderer.render_depth(scene, T)
            img = cv2.imread(str(out / "mav0" / f"cam{cam}" / "data" / f"{int(t)}.png"), cv2.IMREAD_GRAYSCALE)
            _, px, nrm, vis = sample_segments(truth.lines[lines_sel], T, truth.cameras[cam], depth)
            off, strength = edge_offsets(img, px[vis], nrm[vis])
            line_off.append(off[strength > 8.0])
            ppx, pvis = project_points(truth.points[pts_sel], T, truth.cameras[cam], depth, border=10)
            sm = cv2.GaussianBlur(img, (0, 0), 0.8)
            eig = cv2.cornerMinEigenVal(sm, 3)
            for x, y in ppx[pvis]:
                if eig[int(round(y)), int(round(x))] < 0.002:
                    continue  # no visible corner there (e.g. equal grey on both sides)
                ref = cv2.cornerSubPix(sm, np.array([[[x, y]]], np.float32), (4, 4), (-1, -1),
                                       (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)).reshape(2)
                corner_err.append(np.linalg.norm(ref - [x, y]))
                disp.append(ref - [x, y])
    off = np.abs(np.concatenate(line_off))
    corner_err = np.array(corner_err)
    inl = off < 1.0
    print(f"line samples {off.size}: {inl.mean() * 100:.1f} % within 1 px, mean |offset| of those {off[inl].mean():.3f}"
          f" px, median {np.median(off):.3f} px; corners {corner_err.size}: mean {corner_err.mean():.3f} px, "
          f"median {np.median(corner_err):.3f} px, mean displacement {np.mean(disp, axis=0)}")
    assert off.size > 2000 and corner_err.size >= 10
    assert inl.mean() > 0.9
    assert off[inl].mean() < 0.3
    assert np.median(off) < 0.3
    assert corner_err.mean() < 0.6
    assert np.all(np.abs(np.mean(disp, axis=0)) < 0.25)  # no systematic shift


def test_cam1_agrees_with_cam0_through_the_written_extrinsics(replay):
    """Corners found in cam0, lifted with the rendered depth and moved into cam1 with the sensor.yaml extrinsics, land
    on the same corners found in cam1's image."""
    out, _ = replay
    truth = SequenceTruth.load(out)
    scene = prepare(**REPLAY).scene.to_native()
    c0, c1 = truth.cameras
    T_C1_C0 = np.linalg.inv(c1.T_B_C) @ c0.T_B_C
    r0 = c0.renderer()
    errs = []
    for t in truth.frames[::5]:
        img0 = cv2.imread(str(out / "mav0" / "cam0" / "data" / f"{int(t)}.png"), cv2.IMREAD_GRAYSCALE)
        img1 = cv2.imread(str(out / "mav0" / "cam1" / "data" / f"{int(t)}.png"), cv2.IMREAD_GRAYSCALE)
        depth0 = r0.render_depth(scene, truth.camera_pose(int(t), 0))
        corners = cv2.goodFeaturesToTrack(img0, 80, 0.05, 15).reshape(-1, 2)
        # Keep real corners: both eigenvalues of the structure tensor large (points on a line or grout band slide
        # along it under cornerSubPix - the aperture problem - whatever the geometry).
        ev = cv2.cornerEigenValsAndVecs(cv2.GaussianBlur(img0, (0, 0), 1.0), 5, 3)
        ratio = np.array([ev[int(round(y)), int(round(x)), 1] / max(ev[int(round(y)), int(round(x)), 0], 1e-12)
                          for x, y in corners])
        corners = corners[ratio > 0.25]
        corners = cv2.cornerSubPix(img0, corners.reshape(-1, 1, 2).astype(np.float32), (4, 4), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)).reshape(-1, 2)
        for x, y in corners:
            z = depth0[int(round(y)), int(round(x))]
            win = depth0[int(y) - 2:int(y) + 3, int(x) - 2:int(x) + 3]
            if z <= 0 or win.size < 25 or np.ptp(win) > 0.02 * z:
                continue  # corner on a depth discontinuity: its depth is ambiguous
            # Undistort by fixed-point iteration of the radtan model, then lift and move to cam1.
            fx, fy, cx, cy = c0.intrinsics
            uv = np.array([(x - cx) / fx, (y - cy) / fy])
            for _ in range(50):
                d = project(c0, np.array([[uv[0], uv[1], 1.0]]))[0]
                uv += (np.array([x, y]) - d) / [fx, fy]
            p0 = np.array([uv[0], uv[1], 1.0]) * z
            p1 = T_C1_C0[:3, :3] @ p0 + T_C1_C0[:3, 3]
            q = project(c1, p1[None])[0]
            if not (10 < q[0] < 741 and 10 < q[1] < 469):
                continue
            ref = cv2.cornerSubPix(img1, q.reshape(1, 1, 2).astype(np.float32), (4, 4), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)).reshape(2)
            errs.append(np.linalg.norm(ref - q))
    errs = np.array(errs)
    print(f"stereo transfer of {errs.size} corners: median {np.median(errs):.3f} px, mean of those < 2 px "
          f"{errs[errs < 2].mean():.3f} px")
    assert errs.size >= 30
    assert np.median(errs) < 0.5
    assert (errs < 1.5).mean() > 0.8


# ------------------------------------------------------------------------------------------- scenes and determinism
@pytest.mark.parametrize("name", ["room", "hall", "lowtex", "mixed"])
def test_scene_objects_keep_their_distance_from_every_camera_centre(name):
    s = builtin_loop(duration=12.0)
    spline, _ = SplineTrajectory.fit(s, int(s.t_ns[0]), int(s.t_ns[-1]))
    st = spline.evaluate(s.t_ns)
    centres = np.vstack([st.p] + [st.p + st.R @ c.T_B_C[:3, 3] for c in (EUROC_CAM0, EUROC_CAM1)])
    spec = build_scene(name, centres, seed=11)
    lo, hi = spec.bounds
    assert np.all(centres.min(axis=0) - lo > 0.5) and np.all(hi - centres.max(axis=0) > 0.5)
    dmin = np.inf
    for o, u, v, _, _ in spec.quads:
        # Distance to the parallelogram (axes are orthogonal for every quad the scenes make).
        uu, vv = u @ u, v @ v
        assert abs(u @ v) < 1e-9 * np.sqrt(uu * vv)
        d = centres - o
        s_ = np.clip(d @ u / uu, 0, 1)
        t_ = np.clip(d @ v / vv, 0, 1)
        closest = o + s_[:, None] * u + t_[:, None] * v
        dmin = min(dmin, np.linalg.norm(centres - closest, axis=1).min())
    print(f"{name}: {len(spec.quads)} quads, {len(spec.lines)} lines, {len(spec.points)} points, closest surface "
          f"{dmin:.2f} m")
    assert dmin >= 0.5
    assert len(spec.lines) > 100 and len(spec.points) > 50


def test_lowtex_has_fewer_corners_than_room(tmp_path):
    counts = {}
    for name in ("room", "lowtex"):
        out = tmp_path / name
        simulate("builtin:loop", name, out, seed=2, start=6.0, duration=1.0)
        imgs = sorted((out / "mav0" / "cam0" / "data").glob("*.png"))[::5]
        n = [len(cv2.goodFeaturesToTrack(cv2.imread(str(p), 0), 5000, 0.01, 5)) for p in imgs]
        counts[name] = float(np.mean(n))
    print(f"Shi-Tomasi corners per frame: {counts}")
    assert counts["room"] > 500
    assert counts["lowtex"] < 0.25 * counts["room"]


def tree_digest(root: Path) -> dict:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_same_arguments_give_identical_bytes(tmp_path):
    args = dict(trajectory="builtin:loop", scene="mixed", seed=5, start=5.0, duration=1.0, blur=True,
                exposure_changes=True)
    simulate(out_dir=tmp_path / "a", **args)
    simulate(out_dir=tmp_path / "b", **args)
    simulate(out_dir=tmp_path / "c", **{**args, "seed": 6})
    a, b, c = (tree_digest(tmp_path / x) for x in "abc")
    assert len(a) > 40 and a == b
    assert a != c


def test_real_imu_mode_keeps_the_real_samples(tmp_path):
    micro = SHARED / "euroc" / "V1_01_easy_micro" / "mav0"
    need_shared(micro)
    imu_csv = micro / "imu0" / "data.csv"
    gt_csv = micro / "state_groundtruth_estimate0" / "data.csv"
    summary = simulate(str(gt_csv), "room", tmp_path / "real", seed=0, start=30.0, duration=1.5,
                       real_imu=str(imu_csv))
    t_out, out = read_csv_ns(tmp_path / "real" / "mav0" / "imu0" / "data.csv")
    t_in, inp = read_csv_ns(imu_csv)
    i0 = int(np.searchsorted(t_in, t_out[0]))
    np.testing.assert_allclose(out, inp[i0:i0 + t_out.size], rtol=1e-12, atol=1e-12)
    assert np.array_equal(t_out, t_in[i0:i0 + t_out.size])
    _, gt = read_csv_ns(tmp_path / "real" / "mav0" / "state_groundtruth_estimate0" / "data.csv")
    assert np.all(np.abs(gt[:, 13:16].mean(axis=0)) > 1e-3)   # the file's accelerometer biases are carried over
    assert summary["frames"] == 30 or summary["frames"] == 31


def test_bad_inputs_name_the_problem(tmp_path):
    with pytest.raises(InputError, match="unknown scene"):
        prepare("builtin:loop", "garden")
    with pytest.raises(InputError, match="unknown built-in"):
        load_trajectory("builtin:spiral")
    with pytest.raises(InputError, match="no such file"):
        load_trajectory(str(tmp_path / "missing.txt"))
    bad = tmp_path / "bad.txt"
    bad.write_text("# t x y z qx qy qz qw\n1.0 0 0 0 0 0 0 1\n1.005 0 0 0 0 0 0 1\n1.01 0 0 x 0 0 0 1\n")
    with pytest.raises(InputError, match=r"bad.txt:4"):
        load_trajectory(str(bad))
    with pytest.raises(InputError, match="duration"):
        prepare("builtin:loop", "room", duration=0.2)
    with pytest.raises(InputError, match="imu-noise"):
        prepare("builtin:loop", "room", imu_noise=str(tmp_path / "nope.yaml"))


def test_imu_noise_has_the_requested_densities(tmp_path):
    from linnet.sim.imu import ImuNoise, synthesize

    s = builtin_loop()
    spline, _ = SplineTrajectory.fit(s, int(s.t_ns[0]), int(s.t_ns[-1]))
    t = s.t_ns[0] + np.arange(5000) * 5_000_000
    noise = ImuNoise()
    imu = synthesize(spline, t, noise, np.random.default_rng(0))
    truth = spline.evaluate(t)
    dt = 0.005
    white_g = imu.gyr - truth.omega_B - imu.bias_gyr
    white_a = imu.acc - truth.f_B - imu.bias_acc
    np.testing.assert_allclose(white_g.std(), noise.gyroscope_noise_density / np.sqrt(dt), rtol=0.05)
    np.testing.assert_allclose(white_a.std(), noise.accelerometer_noise_density / np.sqrt(dt), rtol=0.05)
    np.testing.assert_allclose(np.diff(imu.bias_gyr, axis=0).std(), noise.gyroscope_random_walk * np.sqrt(dt),
                               rtol=0.05)
    np.testing.assert_allclose(np.diff(imu.bias_acc, axis=0).std(), noise.accelerometer_random_walk * np.sqrt(dt),
                               rtol=0.05)
    # A Kalibr-style YAML (with OpenCV's %YAML header) sets the densities; unknown keys are ignored.
    f = tmp_path / "imu.yaml"
    f.write_text("%YAML:1.0\nrate_hz: 200\ngyroscope_noise_density: 1.0e-3\naccelerometer_random_walk: 4.0e-4\n")
    custom = ImuNoise.from_spec(str(f))
    assert custom.gyroscope_noise_density == 1e-3 and custom.accelerometer_random_walk == 4e-4
    assert custom.accelerometer_noise_density == noise.accelerometer_noise_density
    none = synthesize(spline, t, ImuNoise.none(), np.random.default_rng(0))
    np.testing.assert_array_equal(none.gyr, truth.omega_B)
