"""linnet.bags and `linnet convert`: ROS1 / ROS2 (sqlite3, MCAP) bags written from the EuRoC micro set round-trip to
an identical EuRoC folder; records stream in header-stamp order; bad input is a one-line BagError."""
from __future__ import annotations

import filecmp
from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import require_shared_data

from linnet import bags
from linnet.bags import BagError, BagTopics, FrameRecord, ImuRecord

MICRO = "euroc/V1_01_easy_micro"
N_FRAMES = 20
BAG_KINDS = [("ros1", 1, "sqlite3"), ("ros2_sqlite3", 2, "sqlite3"), ("ros2_mcap", 2, "mcap")]


def _bag_name(version: int) -> str:
    return "seq.bag" if version == 1 else "seq"


@pytest.fixture(scope="module")
def micro() -> Path:
    return require_shared_data(MICRO)


@pytest.fixture(scope="module", params=BAG_KINDS, ids=[k[0] for k in BAG_KINDS])
def bag(request, micro, tmp_path_factory) -> Path:
    kind, version, storage = request.param
    path = tmp_path_factory.mktemp(kind) / _bag_name(version)
    return bags.write_bag_from_euroc(micro, path, version, N_FRAMES, storage=storage)


@pytest.fixture(scope="module")
def ros1_bag(micro, tmp_path_factory) -> Path:
    return bags.write_bag_from_euroc(micro, tmp_path_factory.mktemp("ros1") / "seq.bag", 1, N_FRAMES)


def _csv_rows(path: Path) -> list:
    return [line for line in path.read_text().splitlines() if line and not line.startswith("#")]


def _source(micro: Path, n_frames: int = N_FRAMES):
    """(frame stamps, IMU array [t, w, a]) the bag writer takes from the micro set."""
    stamps = [int(r.split(",")[0]) for r in _csv_rows(micro / "mav0" / "cam0" / "data.csv")][:n_frames]
    imu = np.array([[float(x) for x in r.split(",")] for r in _csv_rows(micro / "mav0" / "imu0" / "data.csv")])
    t_imu = np.array([int(r.split(",")[0]) for r in _csv_rows(micro / "mav0" / "imu0" / "data.csv")])
    keep = (t_imu >= stamps[0]) & (t_imu <= stamps[-1])
    return stamps, t_imu[keep], imu[keep, 1:]


# ------------------------------------------------------------------------------------------------------------------
# Round trip


def test_convert_gives_the_source_euroc_folder_back(bag, micro, tmp_path):
    out = tmp_path / "euroc"
    stats = bags.convert_bag(bag, out, calib_from=micro)
    stamps, t_imu, imu = _source(micro)
    assert (stats.frames, stats.imu_samples, stats.unpaired_dropped, stats.late_frames_dropped) == \
        (N_FRAMES, len(t_imu), 0, 0)
    assert (stats.t_first_ns, stats.t_last_ns) == (stamps[0], stamps[-1])
    assert stats.notes == []
    src, dst = micro / "mav0", out / "mav0"
    for cam in ("cam0", "cam1"):
        assert (dst / cam / "data.csv").read_text().splitlines() == \
            (src / cam / "data.csv").read_text().splitlines()[: N_FRAMES + 1]
        assert sorted(p.name for p in (dst / cam / "data").iterdir()) == [f"{t}.png" for t in stamps]
        for t in stamps:
            written = cv2.imread(str(dst / cam / "data" / f"{t}.png"), cv2.IMREAD_UNCHANGED)
            original = cv2.imread(str(src / cam / "data" / f"{t}.png"), cv2.IMREAD_UNCHANGED)
            assert written.dtype == np.uint8 and np.array_equal(written, original), (cam, t)
        assert filecmp.cmp(dst / cam / "sensor.yaml", src / cam / "sensor.yaml", shallow=False)
    assert filecmp.cmp(dst / "imu0" / "sensor.yaml", src / "imu0" / "sensor.yaml", shallow=False)
    lines = (dst / "imu0" / "data.csv").read_text().splitlines()
    assert lines[0] == (src / "imu0" / "data.csv").read_text().splitlines()[0] == bags.IMU_CSV_HEADER
    rows = [line.split(",") for line in lines[1:]]
    assert [int(r[0]) for r in rows] == t_imu.tolist()
    assert np.array_equal(np.array([[float(x) for x in r[1:]] for r in rows]), imu)   # bit-identical float64


def test_without_calibration_the_summary_says_what_is_missing(ros1_bag, tmp_path):
    stats = bags.convert_bag(ros1_bag, tmp_path / "euroc")
    assert not list((tmp_path / "euroc").rglob("sensor.yaml"))
    assert len(stats.notes) == 1 and "sensor.yaml" in stats.notes[0] and "--calib-from" in stats.notes[0]


def test_mono_conversion_writes_cam0_only(ros1_bag, tmp_path):
    stats = bags.convert_bag(ros1_bag, tmp_path / "euroc", BagTopics(cam1=None))
    assert stats.frames == N_FRAMES
    assert sorted(p.name for p in (tmp_path / "euroc" / "mav0").iterdir()) == ["cam0", "imu0"]


# ------------------------------------------------------------------------------------------------------------------
# Streaming


def test_records_stream_in_header_stamp_order_although_the_bag_is_in_receive_order(bag):
    with bags.open_bag(bag) as reader:
        stamps_in_bag_order = [reader.deserialize(raw, c.msgtype).header.stamp for c, _, raw in reader.messages()]
    stamps_in_bag_order = [s.sec * 10**9 + s.nanosec for s in stamps_in_bag_order]
    assert stamps_in_bag_order != sorted(stamps_in_bag_order)      # the look-ahead re-ordering has work to do

    stream = bags.read_bag(bag)
    records = list(stream)
    t = [r.t_ns for r in records]
    assert t == sorted(t)
    t_imu = [r.t_ns for r in records if isinstance(r, ImuRecord)]
    assert all(b > a for a, b in zip(t_imu, t_imu[1:]))
    for prev, rec in zip(records, records[1:]):     # a frame comes after every IMU sample of equal stamp
        if isinstance(prev, FrameRecord) and isinstance(rec, ImuRecord):
            assert rec.t_ns > prev.t_ns
    frames = [r for r in records if isinstance(r, FrameRecord)]
    assert len(frames) == N_FRAMES and all(f.right is not None and f.left.shape == (480, 752) for f in frames)
    assert stream.stats.messages_read == stream.stats.messages_total == len(t_imu) + 2 * N_FRAMES


def test_a_window_shorter_than_the_image_delay_loses_frames_and_counts_them(ros1_bag):
    # Images are received 20 (cam0) / 27 (cam1) ms after their stamp, IMU samples 1-2 ms after theirs.
    mono = bags.read_bag(ros1_bag, BagTopics(cam1=None), lookahead_s=0.005)
    records = list(mono)
    assert mono.stats.late_frames_dropped > 0
    assert mono.stats.frames + mono.stats.late_frames_dropped == N_FRAMES
    assert [r.t_ns for r in records] == sorted(r.t_ns for r in records)
    stereo = bags.read_bag(ros1_bag, lookahead_s=0.005)     # cam0 images expire before their cam1 partner arrives
    records = list(stereo)
    assert stereo.stats.frames < N_FRAMES
    assert 2 * stereo.stats.frames + stereo.stats.unpaired_dropped + 2 * stereo.stats.late_frames_dropped \
        == 2 * N_FRAMES
    assert [r.t_ns for r in records] == sorted(r.t_ns for r in records)


@pytest.mark.parametrize("encoding", ["8UC1", "mono16", "bgr8", "rgb8", "png"])
def test_image_encodings_decode_to_the_original_grey_pixels(encoding, micro, tmp_path):
    bag = bags.write_bag_from_euroc(micro, tmp_path / "enc.bag", 1, 2, encoding=encoding)
    frames = [r for r in bags.read_bag(bag) if isinstance(r, FrameRecord)]
    assert len(frames) == 2
    for f in frames:
        for cam, img in (("cam0", f.left), ("cam1", f.right)):
            original = cv2.imread(str(micro / "mav0" / cam / "data" / f"{f.t_ns}.png"), cv2.IMREAD_UNCHANGED)
            assert img.dtype == np.uint8 and np.array_equal(img, original), (encoding, cam)


# ------------------------------------------------------------------------------------------------------------------
# Hand-made bags: pairing, bad encodings, bad IMU stamps

T0 = 1_700_000_000_000_000_000


def _write_ros1(path: Path, messages: list) -> Path:
    """messages: (topic, 'imu' | image encoding, header stamp ns, receive ns) -> a ROS1 bag of 4x3 images."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    T = ts.types

    def header(t):
        return T["std_msgs/msg/Header"](seq=0, stamp=T["builtin_interfaces/msg/Time"](sec=t // 10**9,
                                                                                      nanosec=t % 10**9), frame_id="")

    with Writer(path) as writer:
        conns = {}
        for topic, kind, t, receive in sorted(messages, key=lambda m: m[3]):
            msgtype = bags.IMU_TYPE if kind == "imu" else bags.IMAGE_TYPE
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            if kind == "imu":
                v = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.81)
                msg = T[msgtype](header=header(t), orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0,
                                                                                                 w=1.0),
                                 orientation_covariance=np.zeros(9), angular_velocity=v,
                                 angular_velocity_covariance=np.zeros(9), linear_acceleration=v,
                                 linear_acceleration_covariance=np.zeros(9))
            else:
                msg = T[msgtype](header=header(t), height=3, width=4, encoding=kind, is_bigendian=0, step=4,
                                 data=np.full(12, t % 251, dtype=np.uint8))
            writer.write(conns[topic], receive, ts.serialize_ros1(msg, msgtype))
    return path


def _ms(k: float) -> int:
    return T0 + int(k * 1e6)


def test_stereo_images_pair_by_identical_stamp_and_unpaired_ones_are_counted(tmp_path):
    msgs = [("/imu0", "imu", _ms(k), _ms(k + 1)) for k in range(0, 400, 5)]
    msgs += [("/cam0/image_raw", "mono8", _ms(k), _ms(k + 20)) for k in (50, 100, 150, 200)]
    msgs += [("/cam1/image_raw", "mono8", _ms(k), _ms(k + 30)) for k in (50, 100, 200, 250)]
    msgs += [("/cam1/image_raw", "mono8", _ms(150.001), _ms(181))]          # 1 us off: not a pair
    stream = bags.read_bag(_write_ros1(tmp_path / "pairs.bag", msgs))
    frames = [r for r in stream if isinstance(r, FrameRecord)]
    assert [f.t_ns for f in frames] == [_ms(50), _ms(100), _ms(200)]
    assert all(np.array_equal(f.left, f.right) for f in frames)
    assert stream.stats.unpaired_dropped == 3       # cam0 at 150, cam1 at 150.001 and at 250
    assert stream.stats.imu_samples == 80


def test_unsupported_encoding_is_a_bag_error_naming_topic_and_encoding(tmp_path):
    msgs = [("/imu0", "imu", _ms(0), _ms(1)), ("/cam0/image_raw", "yuv422", _ms(0), _ms(2)),
            ("/cam1/image_raw", "mono8", _ms(0), _ms(3))]
    bag = _write_ros1(tmp_path / "yuv.bag", msgs)
    out = tmp_path / "out"
    with pytest.raises(BagError, match=r"/cam0/image_raw: unsupported image encoding 'yuv422'"):
        bags.convert_bag(bag, out)
    assert not out.exists()                          # nothing half-written is left


def test_non_monotonic_imu_stamps_are_a_bag_error_naming_topic_and_times(tmp_path):
    msgs = [("/imu0", "imu", _ms(k), _ms(i + 1)) for i, k in enumerate([0, 5, 10, 8, 15])]
    msgs += [("/cam0/image_raw", "mono8", _ms(0), _ms(20)), ("/cam1/image_raw", "mono8", _ms(0), _ms(21))]
    bag = _write_ros1(tmp_path / "imu.bag", msgs)
    with pytest.raises(BagError, match=rf"/imu0: time stamps not strictly increasing \({_ms(8)} ns after {_ms(10)} ns"):
        list(bags.read_bag(bag))


# ------------------------------------------------------------------------------------------------------------------
# Bad input, through the library and the CLI


def test_missing_path(tmp_path):
    with pytest.raises(BagError, match=r"nope\.bag: no such file or folder"):
        bags.read_bag(tmp_path / "nope.bag")


@pytest.mark.parametrize("name", ["notes.txt", "notes.bag", "folder"])
def test_not_a_bag(name, tmp_path):
    path = tmp_path / name
    if name == "folder":
        path.mkdir()
    else:
        path.write_text("this is not a bag\n")
    with pytest.raises(BagError, match="not a (readable )?ROS") as e:
        bags.read_bag(path)
    assert str(path) in str(e.value)


def test_truncated_bag_is_a_bag_error(ros1_bag, tmp_path):
    cut = tmp_path / "cut.bag"
    cut.write_bytes(ros1_bag.read_bytes()[: ros1_bag.stat().st_size // 2])
    with pytest.raises(BagError, match=str(cut)):
        list(bags.read_bag(cut))


def test_wrong_topic_lists_the_topics_of_the_bag(ros1_bag):
    with pytest.raises(BagError) as e:
        bags.read_bag(ros1_bag, BagTopics(imu="/imu"))
    message = str(e.value)
    assert "no topic /imu;" in message
    for listed in ("/cam0/image_raw (sensor_msgs/msg/Image)", "/cam1/image_raw (sensor_msgs/msg/Image)",
                   "/imu0 (sensor_msgs/msg/Imu)"):
        assert listed in message
    with pytest.raises(BagError, match=r"topic /cam0/image_raw \(imu\) is sensor_msgs/msg/Image, expected"):
        bags.read_bag(ros1_bag, BagTopics(imu="/cam0/image_raw", cam0="/cam1/image_raw", cam1=None))


def test_non_empty_output_folder_is_refused_and_left_alone(ros1_bag, tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(BagError, match="not empty"):
        bags.convert_bag(ros1_bag, tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_output_that_cannot_be_created(ros1_bag, tmp_path):
    (tmp_path / "file").write_text("")
    with pytest.raises(BagError, match="cannot create"):
        bags.convert_bag(ros1_bag, tmp_path / "file" / "euroc")


def _cli(capsys, *args):
    from linnet.cli import main

    with pytest.raises(SystemExit) as e:
        main(["convert", *map(str, args)])
    out, err = capsys.readouterr()
    return e.value.code, out, err


def test_cli_converts_and_prints_a_summary(ros1_bag, micro, tmp_path, capsys):
    code, out, err = _cli(capsys, ros1_bag, "--out", tmp_path / "euroc", "--calib-from", micro)
    assert code == 0, err
    assert f"{len(_source(micro)[1])} IMU samples, {N_FRAMES} stereo frames, 0 unpaired images dropped" in out
    assert (tmp_path / "euroc" / "mav0" / "cam1" / "sensor.yaml").is_file()


@pytest.mark.parametrize("case", ["missing", "text", "topic", "not_empty"])
def test_cli_bad_input_is_one_line_and_exit_code_1(case, ros1_bag, tmp_path, capsys):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("")
    (tmp_path / "notes.txt").write_text("hello\n")
    args = {"missing": [tmp_path / "nope.bag", "--out", tmp_path / "o"],
            "text": [tmp_path / "notes.txt", "--out", tmp_path / "o"],
            "topic": [ros1_bag, "--out", tmp_path / "o", "--imu-topic", "/imu"],
            "not_empty": [ros1_bag, "--out", tmp_path / "full", "--quiet"]}[case]
    code, _, err = _cli(capsys, *args)
    assert code == 1
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("linnet: error: "), err
    assert not (tmp_path / "o").exists()


def test_cli_mono_and_cam1_topic_is_a_usage_error(ros1_bag, tmp_path, capsys):
    code, _, err = _cli(capsys, ros1_bag, "--out", tmp_path / "o", "--mono", "--cam1-topic", "/cam1/image_raw")
    assert code == 2 and "exclude each other" in err
