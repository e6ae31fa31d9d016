"""Linnet: point-and-line visual-inertial SLAM (stereo/mono + IMU).

    import linnet
    system = linnet.System(linnet.Config.euroc_stereo_imu())
    system.add_imu(t_ns, acc, gyr)          # numpy 3-vectors, SI units, body (IMU) frame
    system.add_stereo(t_ns, left, right)    # numpy uint8 images
    system.finish()
    traj = system.trajectory()              # dict of numpy arrays: t_ns, position, quaternion_xyzw, ...

    traj = linnet.run_dataset("path/to/MH_01_easy")   # a EuRoC folder, deterministic

API (see help(linnet.<name>)):
    Config       configuration: defaults, for_euroc / for_kalibr calibrations, set("a.b", value), YAML in / out
    System       the SLAM system fed frame by frame (add_imu accepts arrays of samples too)
    FrameResult  what the System reports per frame (set_callback, results())
    StreamRun    a run fed sample by sample with a RunSummary at the end (ROS bags, drivers)
    RunSummary   a whole run's results, map, timings and warnings
    run_dataset  run a EuRoC folder and get numpy arrays
    Error        base of InputError (bad data, names the file), ConfigError (names the key), UsageError
Modules: linnet.evaluation (APE / RPE), linnet.sim (simulator), linnet.bags (ROS bags), linnet.api.

The compiled core is loaded on first use, so the pure-Python parts (evaluation, plots, simulator scenes) import
without it.
"""

__version__ = "0.1.0"

_CORE_NAMES = ("Config", "ConfigError", "Error", "FrameResult", "InputError", "RunSummary", "StreamRun", "System",
               "UsageError")

__all__ = list(_CORE_NAMES) + ["run_dataset"]


def __getattr__(name):
    if name in _CORE_NAMES:
        from linnet import _linnet

        return getattr(_linnet, name)
    if name == "run_dataset":
        from linnet.api import run_dataset

        return run_dataset
    raise AttributeError(f"module 'linnet' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
