"""Running Linnet on a ROS bag: the bag's records (linnet.bags) fed to a StreamRun in the order runEuroc feeds a EuRoC
folder, so that a bag and the folder it was made from give the same trajectory.

Feeding order (as runEuroc): IMU from `estimator.init.gravity_window_s` + 0.05 s before the first frame run; each
frame after every IMU sample up to and including the first one at or after its time stamp; four IMU samples past the
last frame.
"""
from __future__ import annotations

import time
from collections import deque
from pathlib import Path
from typing import Callable, Optional, Union

import numpy as np

from linnet import _linnet
from linnet.bags import BagError, BagTopics, FrameRecord, ImuRecord, read_bag

PathLike = Union[str, Path]

#: IMU samples fed past the last frame (as runEuroc).
TAIL_IMU_SAMPLES = 4
#: Frames read to measure a bag's frame rate.
RATE_PROBE_FRAMES = 21


def is_bag(path: PathLike) -> bool:
    """A ROS1 .bag file, a ROS2 bag folder (metadata.yaml), or any file that is not a folder (left to the bag reader
    to accept or to refuse with a clear error)."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.exists()


def frame_rate(path: PathLike, topics: BagTopics) -> float:
    """The camera frame rate of a bag, Hz: the median interval of its first frames."""
    stamps = []
    with read_bag(path, topics) as stream:
        for record in stream:
            if isinstance(record, FrameRecord):
                stamps.append(record.t_ns)
                if len(stamps) >= RATE_PROBE_FRAMES:
                    break
    steps = np.diff(stamps)
    steps = steps[steps > 0]
    if len(steps) < 1:
        raise BagError(f"{path}: fewer than two frames with distinct stamps on {topics.cam0}: cannot tell the frame rate")
    return 1e9 / float(np.median(steps))


def run_bag(path: PathLike, topics: BagTopics, config: _linnet.Config, *, max_frames: int = -1,
            start_s: float = 0.0, realtime_speed: float = 0.0,
            progress: Optional[Callable[[int, int], None]] = None) -> "_linnet.RunSummary":
    """Runs a bag (blocking and deterministic, or paced at `realtime_speed` > 0) and returns the RunSummary, as
    run_euroc does for a folder. `start_s` skips the first seconds of frames, `max_frames` >= 0 stops after that
    many. BagError for a bad bag; linnet errors from the System."""
    from linnet.api import config_value

    lookback_ns = int(round((config_value(config, "estimator.init.gravity_window_s") + 0.05) * 1e9))
    if max_frames == 0:
        raise _linnet.UsageError("no frames selected (max_frames 0)")
    run = _linnet.StreamRun(config, realtime_speed)
    history: deque = deque()     # IMU samples before the first frame, within the look-back
    pending: deque = deque()     # frames waiting for an IMU sample at or after their time (several across a gap)
    last_imu_t: Optional[int] = None
    first_frame_t: Optional[int] = None
    started = False
    tail = -1                    # IMU samples still to feed after the last frame (-1: not there yet)
    total = max_frames if max_frames >= 0 else 0

    def add_frame(frame: FrameRecord, load_cpu_s: float) -> None:
        try:
            run.add_frame(frame.t_ns, frame.left, frame.right, load_cpu_s)
        except _linnet.UsageError as e:  # e.g. an image of another size than the calibration's
            raise BagError(f"{path}: frame at {frame.t_ns} ns on {topics.cam0}: {e}") from None
        if progress:
            progress(run.frames, total)

    with read_bag(path, topics) as stream:
        cpu0 = time.thread_time()
        for record in stream:
            read_cpu = time.thread_time() - cpu0
            if isinstance(record, ImuRecord):
                if not started:
                    history.append(record)
                    while history and history[0].t_ns < record.t_ns - lookback_ns - 1_000_000_000:
                        history.popleft()  # only the look-back before the (still unknown) first frame is kept
                    continue
                run.add_imu(record.t_ns, record.acc, record.gyr)
                last_imu_t = record.t_ns
                while pending and record.t_ns >= pending[0][0].t_ns:
                    add_frame(*pending.popleft())
                if tail > 0 and not pending:
                    tail -= 1
                    if tail == 0:
                        break
            else:
                if tail >= 0:
                    continue
                if first_frame_t is None:
                    first_frame_t = record.t_ns
                if record.t_ns < first_frame_t + int(round(start_s * 1e9)):
                    continue
                if not started:
                    started = True
                    for imu in history:
                        if imu.t_ns >= record.t_ns - lookback_ns:
                            run.add_imu(imu.t_ns, imu.acc, imu.gyr)
                            last_imu_t = imu.t_ns
                    history.clear()
                if not pending and last_imu_t is not None and last_imu_t >= record.t_ns:
                    add_frame(record, read_cpu)
                else:
                    pending.append((record, read_cpu))
                if max_frames >= 0 and run.frames + len(pending) >= max_frames:
                    # As runEuroc: the sample that covers the last frame, then TAIL_IMU_SAMPLES more.
                    tail = TAIL_IMU_SAMPLES + (1 if pending else 0)
            cpu0 = time.thread_time()
    if pending:  # the IMU ended before these frames: still handed over (the System drops what the IMU never covers)
        run.add_warning(f"{path}: the IMU ({topics.imu}) ends before the last {len(pending)} frame(s)")
        while pending:
            add_frame(pending.popleft()[0], 0.0)
    if run.frames == 0:
        raise BagError(f"{path}: no frame to run on {topics.cam0}"
                       + (f" after --start {start_s:g} s" if start_s > 0 else ""))
    return run.finish()
