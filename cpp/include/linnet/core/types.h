// Basic value types shared by every layer: time, Eigen aliases.
#pragma once

#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace linnet {

/// Time stamps are signed 64-bit nanoseconds everywhere inside Linnet.
using Timestamp = std::int64_t;

inline constexpr double kNanosecondsPerSecond = 1e9;

/// Nanoseconds -> seconds (double). Only for file formats and arithmetic on durations.
inline double toSeconds(Timestamp t) { return static_cast<double>(t) * 1e-9; }

/// Seconds -> nanoseconds, rounded to the nearest nanosecond.
inline Timestamp fromSeconds(double s) {
  return static_cast<Timestamp>(s * kNanosecondsPerSecond + (s >= 0.0 ? 0.5 : -0.5));
}

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Vec15 = Eigen::Matrix<double, 15, 1>;
using Mat2 = Eigen::Matrix2d;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat15 = Eigen::Matrix<double, 15, 15>;
using Quat = Eigen::Quaterniond;  // Hamilton convention (Eigen's)

}  // namespace linnet
