"""Linnet: point-and-line visual-inertial SLAM (stereo/mono + IMU).

    import linnet
    system = linnet.System(linnet.Config.euroc_stereo_imu())
    system.add_imu(t_ns, acc, gyr)          # numpy 3-vectors, SI units, body (IMU) frame
    system.add_stereo(t_ns, left, right)    # numpy uint8 images
    system.finish()
    traj = system.trajectory()              # dict of numpy arrays: t_ns, position, quaternion_xyzw, ...

    traj = linnet.run_dataset("path/to/MH_01_easy")   # a EuRoC folder, deterministic

The compiled core is loaded on first use, so the pure-Python parts (evaluation, plots, simulator scenes) import
without it.
"""

__version__ = "0.1.0"

_CORE_NAMES = ("Config", "ConfigError", "Error", "FrameResult", "InputError", "RunSummary", "System", "UsageError")

__all__ = list(_CORE_NAMES) + ["run_dataset"]


def __getattr__(name):
    if name in _CORE_NAMES:
        from linnet import _linnet

        return getattr(_linnet, name)
    if name == "run_dataset":
        from linnet.api import run_dataset

        return run_dataset
    raise AttributeError(f"module 'linnet' has no attribute {name!r}")
