"""Writers of the EuRoC ASL layout (as in the published EuRoC MAV datasets, Burri et al., IJRR 2016) and of the
scene's ground-truth geometry.

    DIR/mav0/body.yaml
    DIR/mav0/cam{0,1}/sensor.yaml, data.csv (#timestamp [ns],filename), data/<t_ns>.png (8-bit grey)
    DIR/mav0/imu0/sensor.yaml (the noise actually used), data.csv (t_ns, w_xyz [rad/s], a_xyz [m/s^2]; gyro first)
    DIR/mav0/state_groundtruth_estimate0/sensor.yaml, data.csv (t_ns, p, q_wxyz, v, b_w, b_a)
    DIR/sim/lines.csv, points.csv, README.md, info.yaml   (see README_TEXT)

Every number is formatted with a fixed format, so the same inputs give byte-identical files.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

IMU_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
              "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")
GT_HEADER = ("#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
             "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
             "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
             "b_a_RS_S_z [m s^-2]")

README_TEXT = """# Simulated sequence: ground truth of the scene geometry

Written by `linnet simulate`. All coordinates are in the world frame W of the trajectory (metres, z up, gravity along
-z), the same frame as mav0/state_groundtruth_estimate0. Cameras and IMU follow the EuRoC ASL layout in mav0/.

## lines.csv
One physical straight edge per row: `id,x0,y0,z0,x1,y1,z1,kind`. Kinds: `box` / `pillar` (edges of boxes),
`door_frame`, `window_frame`, `panel_frame`, `door`, `window`, `panel`, `poster` (outlines), `skirting`, `pipe`,
`wall_corner`, `wall_ceiling` (room junctions), `floor_tile`, `ceiling_tile` (centre lines of the
1 cm grout bands of low-texture floors and ceilings). Segments may be partly or wholly hidden from a given view:
test visibility with the depth of the rendered scene.

## points.csv
One 3D corner per row: `id,x,y,z,kind` (box / frame / poster / outline vertices, room corners, tile crossings).

## info.yaml
The arguments of the run, the trajectory fit residual, the scene size and the camera/IMU time ranges.
"""


def _yaml_matrix(T: np.ndarray) -> str:
    rows = [", ".join(f"{v:.12g}" for v in T[r]) for r in range(4)]
    return "T_BS:\n  cols: 4\n  rows: 4\n  data: [" + ",\n         ".join(rows) + "]\n"


def write_camera(mav0: Path, cam, t_ns: np.ndarray) -> Path:
    d = mav0 / cam.name
    (d / "data").mkdir(parents=True, exist_ok=True)
    k = cam.coeffs
    (d / "sensor.yaml").write_text(
        "%YAML:1.0\n# General sensor definitions.\nsensor_type: camera\n"
        f"comment: {cam.comment}\n\n# Sensor extrinsics wrt. the body-frame.\n" + _yaml_matrix(cam.T_B_C) +
        f"\n# Camera specific definitions.\nrate_hz: {cam.rate_hz:g}\nresolution: [{cam.width}, {cam.height}]\n"
        "camera_model: pinhole\n"
        f"intrinsics: [{', '.join(f'{v:.12g}' for v in cam.intrinsics)}] #fu, fv, cu, cv\n"
        "distortion_model: radial-tangential\n"
        f"distortion_coefficients: [{', '.join(f'{v:.12g}' for v in k)}]\n", encoding="utf-8")
    with open(d / "data.csv", "w", encoding="utf-8") as f:
        f.write("#timestamp [ns],filename\n")
        for t in t_ns:
            f.write(f"{int(t)},{int(t)}.png\n")
    return d / "data"


def write_imu(mav0: Path, imu, noise, rate_hz: float = 200.0):
    """imu0/data.csv and sensor.yaml. The yaml holds the noise the measurements were made with; when a density is
    zero (noise-free simulation) it holds EuRoC's nominal values instead, for estimators that weight by them (and
    that reject zeros), and says so in a comment."""
    from linnet.sim.imu import ImuNoise

    d = mav0 / "imu0"
    d.mkdir(parents=True, exist_ok=True)
    note = ""
    densities = (noise.gyroscope_noise_density, noise.gyroscope_random_walk, noise.accelerometer_noise_density,
                 noise.accelerometer_random_walk)
    if min(densities) <= 0.0:
        note = ("# NOTE: the measurements were simulated with gyroscope/accelerometer noise densities and random walks "
                "of\n# [" + ", ".join(f"{v:g}" for v in densities) + "]; the values below are EuRoC's nominal "
                "ones, for estimators.\n")
        noise = ImuNoise()
    (d / "sensor.yaml").write_text(
        "%YAML:1.0\n#Default imu sensor yaml file\nsensor_type: imu\n"
        "comment: simulated VI-Sensor IMU (ADIS16448 noise model)\n" + note + "\n"
        "# Sensor extrinsics wrt. the body-frame.\n" + _yaml_matrix(np.eye(4)) + f"rate_hz: {rate_hz:g}\n\n"
        "# inertial sensor noise model parameters (static)\n"
        f"gyroscope_noise_density: {noise.gyroscope_noise_density:.6e}     # [ rad / s / sqrt(Hz) ]\n"
        f"gyroscope_random_walk: {noise.gyroscope_random_walk:.6e}       # [ rad / s^2 / sqrt(Hz) ]\n"
        f"accelerometer_noise_density: {noise.accelerometer_noise_density:.6e}  # [ m / s^2 / sqrt(Hz) ]\n"
        f"accelerometer_random_walk: {noise.accelerometer_random_walk:.6e}    # [ m / s^3 / sqrt(Hz) ]\n",
        encoding="utf-8")
    data = np.column_stack([imu.gyr, imu.acc])
    _write_rows(d / "data.csv", IMU_HEADER, imu.t_ns, data, "%.15g")


def write_groundtruth(mav0: Path, t_ns, state, bias_gyr, bias_acc):
    d = mav0 / "state_groundtruth_estimate0"
    d.mkdir(parents=True, exist_ok=True)
    (d / "sensor.yaml").write_text(
        "%YAML:1.0\n# General sensor definitions.\nsensor_type: visual-inertial\n"
        "comment: simulated ground truth (the continuous-time trajectory the sensors were simulated from)\n\n"
        "# Sensor extrinsics wrt. the body-frame.\n" + _yaml_matrix(np.eye(4)), encoding="utf-8")
    data = np.column_stack([state.p, state.q, state.v, bias_gyr, bias_acc])
    _write_rows(d / "data.csv", GT_HEADER, t_ns, data, "%.12g")


def write_body(mav0: Path):
    mav0.mkdir(parents=True, exist_ok=True)
    (mav0 / "body.yaml").write_text("%YAML:1.0\ncomment: simulated VI-Sensor rig (Linnet trajectory-replay "
                                    "simulator); body frame = IMU frame\n", encoding="utf-8")


def write_scene_truth(sim_dir: Path, scene, info: dict):
    sim_dir.mkdir(parents=True, exist_ok=True)
    with open(sim_dir / "lines.csv", "w", encoding="utf-8") as f:
        f.write("#id,x0 [m],y0 [m],z0 [m],x1 [m],y1 [m],z1 [m],kind\n")
        for i, (a, b, kind) in enumerate(scene.lines):
            f.write(f"{i},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},{b[0]:.6f},{b[1]:.6f},{b[2]:.6f},{kind}\n")
    with open(sim_dir / "points.csv", "w", encoding="utf-8") as f:
        f.write("#id,x [m],y [m],z [m],kind\n")
        for i, (p, kind) in enumerate(scene.points):
            f.write(f"{i},{p[0]:.6f},{p[1]:.6f},{p[2]:.6f},{kind}\n")
    (sim_dir / "README.md").write_text(README_TEXT, encoding="utf-8")
    (sim_dir / "info.yaml").write_text(yaml.safe_dump(info, sort_keys=True), encoding="utf-8")


def _write_rows(path: Path, header: str, t_ns: np.ndarray, data: np.ndarray, fmt: str):
    lines = [header]
    row_fmt = "%d" + ("," + fmt) * data.shape[1]
    for t, row in zip(t_ns, data):
        lines.append(row_fmt % (int(t), *row))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_lines_csv(path) -> tuple[np.ndarray, list]:
    """(N, 2, 3) segments and their kinds from a sim/lines.csv."""
    segs, kinds = [], []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if not line or line.startswith("#"):
            continue
        f = line.split(",")
        segs.append([[float(f[1]), float(f[2]), float(f[3])], [float(f[4]), float(f[5]), float(f[6])]])
        kinds.append(f[7])
    return np.array(segs).reshape(-1, 2, 3), kinds


def read_points_csv(path) -> tuple[np.ndarray, list]:
    pts, kinds = [], []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        if not line or line.startswith("#"):
            continue
        f = line.split(",")
        pts.append([float(f[1]), float(f[2]), float(f[3])])
        kinds.append(f[4])
    return np.array(pts).reshape(-1, 3), kinds
