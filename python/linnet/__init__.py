"""Linnet: point-and-line visual-inertial SLAM (stereo/mono + IMU).

    import linnet
    system = linnet.System(linnet.Config.euroc_stereo_imu())
    system.add_imu(t_ns, acc, gyr)          # numpy 3-vectors, SI units, body (IMU) frame
    system.add_stereo(t_ns, left, right)    # numpy uint8 images
    system.finish()
    traj = system.trajectory()              # dict of numpy arrays: t_ns, position, quaternion_xyzw, ...

    traj = linnet.run_dataset("path/to/MH_01_easy")   # a EuRoC folder, deterministic
"""

__version__ = "0.1.0"

from linnet._linnet import (  # noqa: E402
    Config,
    ConfigError,
    Error,
    FrameResult,
    InputError,
    RunSummary,
    System,
    UsageError,
)
from linnet.api import run_dataset  # noqa: E402

__all__ = [
    "Config",
    "ConfigError",
    "Error",
    "FrameResult",
    "InputError",
    "RunSummary",
    "System",
    "UsageError",
    "run_dataset",
]
