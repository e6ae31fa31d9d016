// How the loop closer's database keeps a keyframe's place description for the rest of the run: single precision
// coordinates and one copy of each descriptor, at about two thirds of PlaceFeatures' memory. On a long flight the
// database is most of what the process adds after the first minute (README, Loop closure).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "linnet/loop/place_matcher.h"

namespace linnet {

struct StoredPlace {
  std::vector<Eigen::Vector2f> uv;  // PlaceFeatures::uv
  cv::Mat descriptors_2d;           // PlaceFeatures::descriptors_2d (exact size)
  std::vector<Eigen::Vector3f> p_C; // PlaceFeatures::p_C
  // The 3D corners' descriptors as rows of descriptors_2d (the tracked corners are in both sets), or, for a
  // description without those rows (rows_3d unknown), their own copy.
  std::vector<std::uint16_t> rows_3d;
  cv::Mat descriptors_3d;
  std::vector<std::array<Eigen::Vector2f, 2>> line_uv;
  std::vector<LbdDescriptor> line_desc;
  std::vector<std::array<Eigen::Vector3f, 2>> line_p_C;

  bool described() const { return !uv.empty() || !line_uv.empty(); }
  /// Heap memory held, bytes.
  std::size_t bytes() const;
};

/// The stored form of a final description (depths and line segments set). The tracked corners' ids, copies and
/// stereo positions and the line ids, which only setPlaceDepths / setPlaceLines need, are not kept. Of the detected
/// corners (those not tracked, strongest first in describePlace), only the first `max_detected` are kept (< 0: all).
StoredPlace storePlace(const PlaceFeatures& f, int max_detected = -1);

/// The description to match with: storePlace's fields back in double precision (rounded to float once).
PlaceFeatures expandPlace(const StoredPlace& s);

}  // namespace linnet
