"""Linnet: point-and-line visual-inertial SLAM (stereo/mono + IMU)."""

__version__ = "0.1.0"
