// Conversions shared by the bindings: per-frame results and maps as dicts of numpy arrays.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <vector>

#include "linnet/core/map_line.h"
#include "linnet/pipeline/system.h"

namespace linnet::python {

namespace py = pybind11;

/// t_ns, position, quaternion_xyzw, velocity, bias_acc, bias_gyr, has_pose, keyframe, frontend_ms, backend_ms,
/// points, lines: one row per frame (only frames with a pose if `only_with_pose`).
py::dict resultsToArrays(const std::vector<FrameResult>& results, bool only_with_pose);
/// points (N x 3), lines (M x 2 x 3), line_ids (M), line_observations (M).
py::dict mapToDict(const std::vector<Vec3>& points, const std::vector<MapLine>& lines);

}  // namespace linnet::python
