"""ROS bag input: read stereo/mono images and IMU samples from a ROS1 ``.bag`` or a ROS2 bag (sqlite3 or MCAP).

Pure Python (the ``rosbags`` package), no ROS installation needed::

    from linnet.bags import BagTopics, ImuRecord, FrameRecord, read_bag, convert_bag

    with read_bag("V1_01_easy.bag", BagTopics()) as stream:     # EuRoC / TUM-VI topic names by default
        for rec in stream:                                       # header-stamp order, IMU before a frame of equal stamp
            if isinstance(rec, ImuRecord): ...                   # rec.t_ns, rec.acc [m/s^2], rec.gyr [rad/s]
            else: ...                                            # rec.t_ns, rec.left (uint8 HxW), rec.right or None
    print(stream.stats)                                          # IMU samples, frames, unpaired images dropped

    convert_bag("V1_01_easy.bag", "out/V1_01_easy", calib_from="EuRoC/V1_01_easy")   # -> out/.../mav0/...

Time stamps are the message header stamps (``sec * 10**9 + nanosec``), never the bag's receive times. Bags are
ordered by receive time, so records are re-sorted by header stamp inside a look-ahead window (default 0.5 s of
header time): a message whose stamp is more than the window behind the newest stamp already read is "late".
Stereo images are paired by identical header stamps; an image whose partner has not arrived within the window is
dropped and counted. Every problem with the input is a :class:`BagError` (a ``ValueError``) naming the bag.
"""
from __future__ import annotations

import csv
import heapq
import shutil
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Iterator, Optional, Union

import numpy as np

PathLike = Union[str, Path]
Progress = Callable[[int, int], None]
"""``progress(messages_read, messages_total)`` of the selected topics."""

IMU_TYPE = "sensor_msgs/msg/Imu"
IMAGE_TYPE = "sensor_msgs/msg/Image"
COMPRESSED_TYPE = "sensor_msgs/msg/CompressedImage"
IMAGE_TYPES = (IMAGE_TYPE, COMPRESSED_TYPE)

DEFAULT_LOOKAHEAD_S = 0.5

IMU_CSV_HEADER = ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
                  "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]")
CAM_CSV_HEADER = "#timestamp [ns],filename"


class BagError(ValueError):
    """A missing, unreadable or unsuitable bag (or output folder); the message names the path."""


@dataclass(frozen=True)
class BagTopics:
    """Topic names to read. The defaults are those of the EuRoC bags and of the TUM-VI bags (both publish
    ``/cam0/image_raw``, ``/cam1/image_raw`` and ``/imu0``). ``cam1=None`` reads a monocular sequence."""

    cam0: str = "/cam0/image_raw"
    cam1: Optional[str] = "/cam1/image_raw"
    imu: str = "/imu0"

    @property
    def stereo(self) -> bool:
        return self.cam1 is not None


@dataclass(frozen=True)
class ImuRecord:
    """One sensor_msgs/Imu sample: header stamp [ns], linear acceleration [m/s^2], angular velocity [rad/s]."""

    t_ns: int
    acc: np.ndarray
    gyr: np.ndarray


@dataclass(frozen=True)
class FrameRecord:
    """One camera frame at header stamp ``t_ns`` [ns]: 8-bit grey images (``right`` is None for mono)."""

    t_ns: int
    left: np.ndarray
    right: Optional[np.ndarray]


Record = Union[ImuRecord, FrameRecord]


@dataclass
class BagStats:
    """Counts of one pass over a bag (filled while iterating; final once the iteration has ended)."""

    path: str
    topics: BagTopics
    messages_total: int = 0          # messages on the selected topics, as the bag's index says
    messages_read: int = 0
    imu_samples: int = 0             # ImuRecords yielded
    frames: int = 0                  # FrameRecords yielded
    unpaired_dropped: int = 0        # stereo images without a partner of identical stamp within the window
    late_frames_dropped: int = 0     # frames whose stamp was behind records already yielded
    t_first_ns: Optional[int] = None
    t_last_ns: Optional[int] = None
    notes: list = field(default_factory=list)

    @property
    def span_s(self) -> float:
        """Time from the first to the last record yielded, seconds (0 when fewer than two)."""
        if self.t_first_ns is None or self.t_last_ns is None:
            return 0.0
        return (self.t_last_ns - self.t_first_ns) * 1e-9

    def summary(self) -> str:
        """One line: IMU samples, frames, unpaired images dropped, time span."""
        kind = "stereo" if self.topics.stereo else "mono"
        text = (f"{self.imu_samples} IMU samples, {self.frames} {kind} frames, "
                f"{self.unpaired_dropped} unpaired images dropped")
        if self.late_frames_dropped:
            text += f", {self.late_frames_dropped} late frames dropped"
        if self.t_first_ns is not None:
            text += f", {self.span_s:.3f} s ({self.t_first_ns} .. {self.t_last_ns} ns)"
        return text


# --------------------------------------------------------------------------------------------------------------------
# Opening a bag


# What a rosbags reader may raise on a damaged or foreign file: besides its ReaderErrors, struct, zstd/lz4, sqlite,
# YAML, Memory-, Overflow-, Type- and KeyErrors from inside its parsers. So everything is caught, but only around the
# calls into rosbags (opening the bag, reading and deserialising a message).
_READER_ERRORS = (Exception,)


def _looks_like_ros1(path: Path) -> bool:
    try:
        with open(path, "rb") as f:
            return f.read(13) == b"#ROSBAG V2.0\n"
    except OSError:
        return False


@contextmanager
def open_bag(path: PathLike) -> Iterator:
    """Open a ROS1 ``.bag`` file or a ROS2 bag (a folder with metadata.yaml, or a lone ``.db3`` / ``.mcap`` file)
    as an open ``rosbags.highlevel.AnyReader``; use as ``with open_bag(p) as reader:``.

    Raises BagError naming the path when it is missing, not a bag or damaged.
    """
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise BagError(f"{path}: no such file or folder")
    if path.is_file() and path.suffix != ".bag" and _looks_like_ros1(path):
        raise BagError(f"{path}: a ROS1 bag must be named *.bag")
    if path.is_file() and path.suffix not in (".bag", ".db3", ".mcap"):
        raise BagError(f"{path}: not a ROS bag (expected a ROS1 .bag file, or a ROS2 bag: a folder with "
                       "metadata.yaml, a .db3 or a .mcap file)")
    try:
        # ROS2 bags recorded before Iron hold no message definitions: fall back to the Humble ones.
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except _READER_ERRORS as e:
        kind = "ROS1 bag" if path.suffix == ".bag" else "ROS2 bag (folder with metadata.yaml, .db3 or .mcap)"
        raise BagError(f"{path}: not a readable {kind}: {_one_line(e)}") from None
    try:
        yield reader
    finally:
        try:
            reader.close()
        except _READER_ERRORS:
            pass


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= 300 else text[:297] + "..."


def bag_topics(path: PathLike) -> dict:
    """``{topic: message type}`` of every topic in the bag (message types as ``pkg/msg/Name``)."""
    with open_bag(path) as reader:
        return {name: info.msgtype for name, info in reader.topics.items()}


def _topic_listing(topics: dict) -> str:
    if not topics:
        return "the bag has no topics"
    return "the bag has: " + ", ".join(f"{name} ({msgtype})" for name, msgtype in sorted(topics.items()))


def _select_connections(reader, path: Path, topics: BagTopics) -> dict:
    """Validate the requested topics against the bag -> ``{role: [connections]}``."""
    available = {name: info.msgtype for name, info in reader.topics.items()}
    wanted = {"imu": (topics.imu, (IMU_TYPE,)), "cam0": (topics.cam0, IMAGE_TYPES)}
    if topics.cam1 is not None:
        if topics.cam1 == topics.cam0:
            raise BagError(f"{path}: cam0 and cam1 are the same topic {topics.cam0}")
        wanted["cam1"] = (topics.cam1, IMAGE_TYPES)
    missing = [name for name, _ in wanted.values() if name not in available]
    if missing:
        raise BagError(f"{path}: no topic {', '.join(missing)}; {_topic_listing(available)}")
    for role, (name, types) in wanted.items():
        if available[name] not in types:
            raise BagError(f"{path}: topic {name} ({role}) is {available[name]}, expected {' or '.join(types)}; "
                           f"{_topic_listing(available)}")
    return {role: [c for c in reader.connections if c.topic == name] for role, (name, _) in wanted.items()}


# --------------------------------------------------------------------------------------------------------------------
# Message decoding


def _stamp_ns(msg) -> int:
    return int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)


_BYTES_PER_PIXEL = {"mono8": 1, "8UC1": 1, "mono16": 2, "16UC1": 2, "bgr8": 3, "rgb8": 3, "bgra8": 4, "rgba8": 4}
_COLOUR_TO_GREY = {"bgr8": "COLOR_BGR2GRAY", "rgb8": "COLOR_RGB2GRAY", "bgra8": "COLOR_BGRA2GRAY",
                   "rgba8": "COLOR_RGBA2GRAY"}
SUPPORTED_ENCODINGS = tuple(_BYTES_PER_PIXEL)


def decode_image(msg, msgtype: str, topic: str, path: PathLike = "") -> np.ndarray:
    """sensor_msgs/Image or CompressedImage -> contiguous uint8 HxW grey image. 16-bit images keep their high byte
    (``value >> 8``); colour images are converted with OpenCV's BGR/RGB-to-grey weights."""
    where = f"{path}: {topic}" if path else topic
    if msgtype == COMPRESSED_TYPE:
        import cv2

        buffer = np.frombuffer(msg.data, np.uint8)
        try:
            img = cv2.imdecode(buffer, cv2.IMREAD_GRAYSCALE) if buffer.size else None
        except cv2.error:  # OpenCV raises on some malformed buffers instead of returning None
            img = None
        if img is None:
            raise BagError(f"{where}: cannot decode compressed image (format '{msg.format}')")
        return img
    enc, h, w, step = msg.encoding, int(msg.height), int(msg.width), int(msg.step)
    if enc not in _BYTES_PER_PIXEL:
        raise BagError(f"{where}: unsupported image encoding '{enc}' (supported: {', '.join(SUPPORTED_ENCODINGS)}, "
                       "or sensor_msgs/CompressedImage)")
    bpp = _BYTES_PER_PIXEL[enc]
    data = np.asarray(msg.data, dtype=np.uint8)
    if h <= 0 or w <= 0 or step < w * bpp or data.size < h * step:
        raise BagError(f"{where}: corrupt image message ({w}x{h}, step {step}, {data.size} bytes, '{enc}')")
    rows = data[: h * step].reshape(h, step)[:, : w * bpp]
    if bpp == 1:
        return rows.copy()          # own, writable memory (the message's may be a read-only view of the bag)
    if bpp == 2:
        return (rows.copy().view(">u2" if msg.is_bigendian else "<u2") >> 8).astype(np.uint8)
    import cv2

    return cv2.cvtColor(np.ascontiguousarray(rows).reshape(h, w, bpp), getattr(cv2, _COLOUR_TO_GREY[enc]))


def _imu_record(msg, t_ns: int) -> ImuRecord:
    a, g = msg.linear_acceleration, msg.angular_velocity
    return ImuRecord(t_ns, np.array([a.x, a.y, a.z], dtype=np.float64), np.array([g.x, g.y, g.z], dtype=np.float64))


# --------------------------------------------------------------------------------------------------------------------
# Streaming


class BagStream:
    """Iterator over the ImuRecords and FrameRecords of a bag in header-stamp order (see :func:`read_bag`).

    ``stats`` (a :class:`BagStats`) is updated while iterating. Close it (or use ``with``) when not iterating to the
    end; the bag is closed automatically once the iteration ends or fails.
    """

    def __init__(self, path: PathLike, topics: BagTopics = BagTopics(), *,
                 lookahead_s: float = DEFAULT_LOOKAHEAD_S, progress: Optional[Progress] = None):
        if not lookahead_s > 0:
            raise ValueError(f"lookahead_s must be > 0, got {lookahead_s}")
        self.path = Path(path)
        self.topics = topics
        self.lookahead_ns = int(round(lookahead_s * 1e9))
        self.stats = BagStats(str(self.path), topics)
        self._progress = progress
        self._stack = ExitStack()
        try:
            reader = self._stack.enter_context(open_bag(self.path))
            self._connections = _select_connections(reader, self.path, topics)
        except BaseException:
            self._stack.close()
            raise
        self._roles = {c.topic: role for role, cs in self._connections.items() for c in cs}
        self.stats.messages_total = sum(c.msgcount for cs in self._connections.values() for c in cs)
        self._records = self._generate(reader)

    def __iter__(self) -> "BagStream":
        return self

    def __next__(self) -> Record:
        return next(self._records)

    def close(self) -> None:
        self._records.close()
        self._stack.close()

    def __enter__(self) -> "BagStream":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- internals ---------------------------------------------------------------------------------------------------

    def _raw_messages(self, reader) -> Iterator:
        """(role, msgtype, topic, message) in bag order; rosbags' errors become BagError."""
        conns = [c for cs in self._connections.values() for c in cs]
        it = reader.messages(connections=conns)
        while True:
            try:
                conn, _, raw = next(it)
                msg = reader.deserialize(raw, conn.msgtype)
            except StopIteration:
                return
            except _READER_ERRORS as e:
                raise BagError(f"{self.path}: damaged bag: {_one_line(e)}") from None
            yield self._roles[conn.topic], conn.msgtype, conn.topic, msg

    def _generate(self, reader) -> Iterator[Record]:
        try:
            yield from self._ordered(reader)
        finally:
            self._stack.close()

    def _ordered(self, reader) -> Iterator[Record]:
        stats, window = self.stats, self.lookahead_ns
        heap: list = []                  # (t_ns, 0 for IMU / 1 for a frame, sequence number, record)
        pending: dict = {"cam0": {}, "cam1": {}}     # unpaired stereo images by stamp
        newest = None                    # largest header stamp read so far
        last_imu = None                  # previous IMU stamp in bag order
        emitted = None                   # stamp of the last record yielded
        seq = 0

        def pop():
            nonlocal emitted
            t, _, _, rec = heapq.heappop(heap)
            emitted = t
            if isinstance(rec, ImuRecord):
                stats.imu_samples += 1
            else:
                stats.frames += 1
            if stats.t_first_ns is None:
                stats.t_first_ns = t
            stats.t_last_ns = t
            return rec

        for role, msgtype, topic, msg in self._raw_messages(reader):
            stats.messages_read += 1
            if self._progress is not None:
                self._progress(stats.messages_read, stats.messages_total)
            t = _stamp_ns(msg)
            if role == "imu":
                if last_imu is not None and t <= last_imu:
                    raise BagError(f"{self.path}: IMU topic {topic}: time stamps not strictly increasing "
                                   f"({t} ns after {last_imu} ns)")
                if emitted is not None and t <= emitted:
                    raise BagError(f"{self.path}: IMU topic {topic}: sample at {t} ns read after records up to "
                                   f"{emitted} ns were ordered; it is later than the look-ahead window of "
                                   f"{window * 1e-9:g} s allows")
                last_imu = t
                heapq.heappush(heap, (t, 0, seq, _imu_record(msg, t)))
                seq += 1
            else:
                image = decode_image(msg, msgtype, topic, self.path)
                frame = None
                if not self.topics.stereo:
                    frame = FrameRecord(t, image, None)
                else:
                    other = pending["cam1" if role == "cam0" else "cam0"].pop(t, None)
                    if other is None:
                        if t in pending[role]:       # a second image of the same stamp on one topic
                            stats.unpaired_dropped += 1
                        pending[role][t] = image
                    else:
                        left, right = (image, other) if role == "cam0" else (other, image)
                        frame = FrameRecord(t, left, right)
                if frame is not None:
                    if emitted is not None and t < emitted:
                        stats.late_frames_dropped += 1
                    else:
                        heapq.heappush(heap, (t, 1, seq, frame))
                        seq += 1
            newest = t if newest is None else max(newest, t)
            horizon = newest - window
            for images in pending.values():
                for stale in [s for s in images if s < horizon]:
                    del images[stale]
                    stats.unpaired_dropped += 1
            while heap and heap[0][0] < horizon:
                yield pop()
        stats.unpaired_dropped += sum(len(images) for images in pending.values())
        while heap:
            yield pop()


def read_bag(path: PathLike, topics: BagTopics = BagTopics(), *, lookahead_s: float = DEFAULT_LOOKAHEAD_S,
             progress: Optional[Progress] = None) -> BagStream:
    """Stream the IMU samples and camera frames of a bag in header-stamp order, without loading the bag.

    Yields :class:`ImuRecord` (strictly increasing stamps) and :class:`FrameRecord` (cam0/cam1 paired by identical
    header stamp; ``right=None`` when ``topics.cam1`` is None) in non-decreasing stamp order, a frame after every IMU
    sample of smaller or equal stamp. ``lookahead_s`` [s] is the re-ordering window (see the module docstring).
    The returned :class:`BagStream` has ``stats``. The bag is opened and the topics are checked right away:
    BagError for a missing or damaged bag, missing topics (the message lists the bag's topics and types),
    unsupported image encodings and non-monotonic IMU stamps.
    """
    return BagStream(path, topics, lookahead_s=lookahead_s, progress=progress)


# --------------------------------------------------------------------------------------------------------------------
# Conversion to a EuRoC folder


def _prepare_out_dir(out_dir: Path) -> None:
    if out_dir.exists() or out_dir.is_symlink():
        if not out_dir.is_dir():
            raise BagError(f"{out_dir}: output exists and is not a folder")
        try:
            empty = not any(out_dir.iterdir())
        except OSError as e:
            raise BagError(f"{out_dir}: cannot read the output folder: {e.strerror or e}") from None
        if not empty:
            raise BagError(f"{out_dir}: output folder is not empty")


def _calibration_files(calib_from: Path, sensors: list) -> list:
    mav0 = calib_from / "mav0"
    if not mav0.is_dir():
        raise BagError(f"{calib_from}: not a EuRoC folder (no mav0/) to take the calibration from")
    files = [mav0 / s / "sensor.yaml" for s in sensors]
    missing = [str(f) for f in files if not f.is_file()]
    if missing:
        raise BagError(f"{calib_from}: calibration missing: {', '.join(missing)}")
    return files + ([mav0 / "body.yaml"] if (mav0 / "body.yaml").is_file() else [])


def convert_bag(path: PathLike, out_dir: PathLike, topics: BagTopics = BagTopics(),
                progress: Optional[Progress] = None, *, calib_from: Optional[PathLike] = None,
                lookahead_s: float = DEFAULT_LOOKAHEAD_S) -> BagStats:
    """Write the bag as a EuRoC folder ``out_dir/mav0/{cam0,cam1,imu0}`` (data.csv + data/<t_ns>.png, imu0/data.csv
    with gyro then acc at full precision) and return its :class:`BagStats`.

    ``out_dir`` must not exist or be empty. Bags hold no calibration: with ``calib_from`` (a EuRoC folder) its
    ``mav0/<sensor>/sensor.yaml`` files (and body.yaml) are copied; otherwise ``stats.notes`` says they must be
    provided. On any error (BagError) nothing is left in ``out_dir``.
    """
    import cv2

    out_dir = Path(out_dir)
    sensors = ["cam0"] + (["cam1"] if topics.stereo else []) + ["imu0"]
    _prepare_out_dir(out_dir)
    calib = _calibration_files(Path(calib_from), sensors) if calib_from is not None else None
    with read_bag(path, topics, lookahead_s=lookahead_s, progress=progress) as stream:
        created = not out_dir.exists()
        mav0 = out_dir / "mav0"
        try:
            for s in sensors:
                (mav0 / s / ("data" if s != "imu0" else "")).mkdir(parents=True, exist_ok=True)
        except OSError as e:
            _remove_output(out_dir, created)
            raise BagError(f"{out_dir}: cannot create the output folder: {e.strerror or e}") from None
        try:
            with ExitStack() as files:
                csvs = {s: files.enter_context(open(mav0 / s / "data.csv", "w", newline="\n")) for s in sensors}
                for s in sensors:
                    csvs[s].write((IMU_CSV_HEADER if s == "imu0" else CAM_CSV_HEADER) + "\n")
                cams = [("cam0", "left"), ("cam1", "right")][: len(sensors) - 1]
                for rec in stream:
                    if isinstance(rec, ImuRecord):
                        values = ",".join(_full_precision(x) for x in (*rec.gyr, *rec.acc))
                        csvs["imu0"].write(f"{rec.t_ns},{values}\n")
                        continue
                    name = f"{rec.t_ns}.png"
                    for cam, side in cams:
                        if not cv2.imwrite(str(mav0 / cam / "data" / name), getattr(rec, side)):
                            raise BagError(f"{out_dir}: cannot write {mav0 / cam / 'data' / name}")
                        csvs[cam].write(f"{rec.t_ns},{name}\n")
            stats = stream.stats
            if stats.frames == 0:
                raise BagError(f"{path}: no {'stereo ' if topics.stereo else ''}frames "
                               f"({stats.unpaired_dropped} unpaired images dropped)")
            if calib is not None:
                for f in calib:
                    target = mav0 / f.relative_to(Path(calib_from) / "mav0")
                    shutil.copyfile(f, target)
            else:
                stats.notes.append(f"no calibration in a bag: provide mav0/{{{','.join(sensors)}}}/sensor.yaml "
                                   "(copy them with --calib-from EUROC_DIR, or give a Kalibr camchain with --calib)")
            if stats.imu_samples == 0:
                stats.notes.append(f"no IMU samples on {topics.imu}")
        except BaseException as e:
            _remove_output(out_dir, created)
            if isinstance(e, OSError):
                raise BagError(f"{out_dir}: cannot write the output: {e}") from None
            raise
    return stats


def _full_precision(x: float) -> str:
    """%.17g (reads back to the same float64), with ".0" on integral values as in the EuRoC files."""
    text = f"{x:.17g}"
    return text + ".0" if text.lstrip("-").isdigit() else text


def _remove_output(out_dir: Path, created: bool) -> None:
    """Undo a failed conversion: the folder if this call created it, else what it put inside (mav0/)."""
    shutil.rmtree(out_dir if created else out_dir / "mav0", ignore_errors=True)


# --------------------------------------------------------------------------------------------------------------------
# Writing a bag from a EuRoC folder (tests, examples)


def _read_csv_rows(path: Path) -> list:
    with open(path, newline="") as f:
        return [row for row in csv.reader(f) if row and not row[0].lstrip().startswith("#")]


def _encode_image(grey: np.ndarray, encoding: str):
    """grey uint8 image -> (Image encoding or None for compressed, payload bytes, step, format)."""
    import cv2

    h, w = grey.shape
    if encoding in ("mono8", "8UC1"):
        return encoding, grey.tobytes(), w
    if encoding == "mono16":
        return encoding, (grey.astype("<u2") << 8).tobytes(), 2 * w
    if encoding in ("bgr8", "rgb8"):
        return encoding, np.repeat(grey[:, :, None], 3, axis=2).tobytes(), 3 * w
    if encoding == "png":
        ok, buf = cv2.imencode(".png", grey)
        if not ok:
            raise BagError("cannot encode a PNG image")
        return None, buf.tobytes(), 0
    raise BagError(f"cannot write image encoding '{encoding}' (mono8, 8UC1, mono16, bgr8, rgb8, png)")


def write_bag_from_euroc(euroc_dir: PathLike, bag_path: PathLike, version: int = 1, max_frames: int = 20, *,
                         storage: str = "sqlite3", topics: BagTopics = BagTopics(), encoding: str = "mono8",
                         cam_delay_ms: tuple = (20.0, 27.0), imu_delay_ms: float = 1.0) -> Path:
    """Write the first ``max_frames`` stereo frames of a EuRoC folder (and the IMU samples from the first to the last
    of their stamps) as a bag: ``version`` 1 = ROS1 ``.bag`` file (noetic types), 2 = ROS2 bag folder (humble types)
    with ``storage`` "sqlite3" or "mcap". Messages carry the EuRoC stamps in their headers and are written in
    receive-time order: stamp + ``cam_delay_ms`` (cam0, cam1) [ms] for images, stamp + ``imu_delay_ms`` [ms]
    (+0..1 ms jitter) for IMU samples, so that receive order differs from stamp order. ``encoding``: mono8, 8UC1,
    mono16, bgr8, rgb8 (sensor_msgs/Image) or png (sensor_msgs/CompressedImage). ``topics.cam1=None`` writes
    cam0 only. Returns ``bag_path``.
    """
    import cv2
    from rosbags.typesys import Stores, get_typestore

    euroc_dir, bag_path = Path(euroc_dir), Path(bag_path)
    mav0 = euroc_dir / "mav0"
    if version not in (1, 2):
        raise BagError(f"bag version must be 1 or 2, got {version}")
    if version == 1 and bag_path.suffix != ".bag":
        raise BagError(f"{bag_path}: a ROS1 bag must be named *.bag")
    if bag_path.exists():
        raise BagError(f"{bag_path}: exists already")
    cams = ["cam0"] + (["cam1"] if topics.stereo else [])
    try:
        images = {c: dict((int(r[0]), r[1].strip()) for r in _read_csv_rows(mav0 / c / "data.csv")) for c in cams}
        imu_rows = _read_csv_rows(mav0 / "imu0" / "data.csv")
    except (OSError, ValueError, IndexError) as e:
        raise BagError(f"{euroc_dir}: not a readable EuRoC folder: {e}") from None
    stamps = sorted(set.intersection(*(set(images[c]) for c in cams)))[:max_frames]
    if not stamps:
        raise BagError(f"{euroc_dir}: no frames")
    imu = [(int(r[0]), [float(x) for x in r[1:7]]) for r in imu_rows if stamps[0] <= int(r[0]) <= stamps[-1]]

    # (receive time, topic order, index) of every message, then written in receive-time order.
    events = [(t + int(imu_delay_ms * 1e6) + (i % 3) * 500_000, 0, i) for i, (t, _) in enumerate(imu)]
    for k, cam in enumerate(cams):
        events += [(t + int(cam_delay_ms[k] * 1e6), 1 + k, i) for i, t in enumerate(stamps)]
    events.sort()

    ts = get_typestore(Stores.ROS1_NOETIC if version == 1 else Stores.ROS2_HUMBLE)
    T = ts.types
    names = {0: topics.imu, 1: topics.cam0, 2: topics.cam1}
    image_type = COMPRESSED_TYPE if encoding == "png" else IMAGE_TYPE

    def header(t_ns: int, frame_id: str, seq: int):
        stamp = T["builtin_interfaces/msg/Time"](sec=t_ns // 1_000_000_000, nanosec=t_ns % 1_000_000_000)
        if version == 1:
            return T["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame_id)
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def message(kind: int, i: int):
        if kind == 0:
            t, (wx, wy, wz, ax, ay, az) = imu[i]
            v3, zeros = T["geometry_msgs/msg/Vector3"], np.zeros(9)
            return IMU_TYPE, T[IMU_TYPE](
                header=header(t, "imu0", i), orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                orientation_covariance=np.array([-1.0] + [0.0] * 8), angular_velocity=v3(x=wx, y=wy, z=wz),
                angular_velocity_covariance=zeros, linear_acceleration=v3(x=ax, y=ay, z=az),
                linear_acceleration_covariance=zeros)
        cam, t = cams[kind - 1], stamps[i]
        grey = cv2.imread(str(mav0 / cam / "data" / images[cam][t]), cv2.IMREAD_GRAYSCALE)
        if grey is None:
            raise BagError(f"{euroc_dir}: cannot read image {mav0 / cam / 'data' / images[cam][t]}")
        enc, payload, step = _encode_image(grey, encoding)
        data = np.frombuffer(payload, dtype=np.uint8)
        if enc is None:
            return COMPRESSED_TYPE, T[COMPRESSED_TYPE](header=header(t, cam, i), format="png", data=data)
        return IMAGE_TYPE, T[IMAGE_TYPE](header=header(t, cam, i), height=grey.shape[0], width=grey.shape[1],
                                         encoding=enc, is_bigendian=0, step=step, data=data)

    if version == 1:
        from rosbags.rosbag1 import Writer

        writer, serialize = Writer(bag_path), ts.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer

        plugins = {"sqlite3": StoragePlugin.SQLITE3, "mcap": StoragePlugin.MCAP}
        if storage not in plugins:
            raise BagError(f"unknown ROS2 storage '{storage}' (sqlite3, mcap)")
        writer, serialize = Writer(bag_path, version=8, storage_plugin=plugins[storage]), ts.serialize_cdr
    with writer:
        conns = {k: writer.add_connection(names[k], IMU_TYPE if k == 0 else image_type, typestore=ts)
                 for k in range(1 + len(cams))}
        for receive_ns, kind, i in events:
            msgtype, msg = message(kind, i)
            writer.write(conns[kind], receive_ns, serialize(msg, msgtype))
    return bag_path
