"""Linnet's trajectory-replay simulator: replays a real (EuRoC) or built-in motion through a procedural scene and
writes a EuRoC ASL dataset (stereo PNGs, IMU, ground truth) plus the scene's 3D lines and corners.

    from linnet.sim import simulate
    summary = simulate("builtin:loop", "room", "out/loop_room", seed=0)

Pure-Python parts (trajectories, spline fit, IMU, scenes, writers) import without the compiled core; rendering uses
linnet._linnet.sim (C++).
"""
from linnet.sim.imu import ImuNoise
from linnet.sim.scene import SCENES, build_scene
from linnet.sim.simulator import simulate
from linnet.sim.trajectory import InputError, SplineTrajectory, builtin_loop, load_trajectory

__all__ = ["simulate", "SCENES", "build_scene", "ImuNoise", "InputError", "SplineTrajectory", "builtin_loop",
           "load_trajectory"]
