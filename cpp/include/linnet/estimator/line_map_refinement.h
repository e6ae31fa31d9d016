// Refinement of a map line on every observation of its life.
//
// In the window a line is estimated from the observations of the window's frames only: when the oldest keyframe
// leaves, the line's residuals there go into the marginalisation prior with the line dropped (the thesis' strategy),
// so a line tracked across more keyframes than the window holds loses its early, widest-baseline views. A line that
// leaves the window for the map is therefore re-estimated once more from all its sightings, each at its frame's final
// pose (held fixed), as a local bundle adjustment of that one line (the map-point refinement of keyframe-based SLAM,
// e.g. ORB-SLAM's local mapping, restricted to the line and without moving the poses).
#pragma once

#include <vector>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"
#include "linnet/estimator/factors/line_factor.h"

namespace linnet {

/// One observation of a line: the observing camera's pose in W and the segment's normalised endpoints.
struct LineSighting {
  Pose T_W_C;
  Vec2 s = Vec2::Zero(), e = Vec2::Zero();
  Timestamp t = 0;  // the frame's time, ns (0: unknown)
};

struct LineRefinementOptions {
  double focal_px = 460.0;   // pixels per normalised unit
  double huber_px = 1.5;     // Huber threshold of the endpoint distances, pixels
  int max_iterations = 10;   // Levenberg-Marquardt iterations
};

/// Mean endpoint-to-line distance over the sightings, pixels (+infinity if the line projects to a point in one).
double meanSightingErrorPx(const Vec6& L_W, const std::vector<LineSighting>& sightings, double focal_px);

/// The points of L closest to the rays through a segment's endpoints s, e (normalised) of camera T_W_C; false if a
/// ray misses the depth range [min_depth_m, max_depth_m] (depth along the camera's z) or is parallel to the line.
bool backProjectSegment(const Vec6& L_W, const Pose& T_W_C, const Vec2& s, const Vec2& e, double min_depth_m,
                        double max_depth_m, Vec3* a, Vec3* b);

/// Extends the segment *ext_a-*ext_b on line L by the segment a-b on L (which is the first one if !*has_extent): the
/// two extreme points along L.
void extendOnLine(const Vec6& L, const Vec3& a, const Vec3& b, bool* has_extent, Vec3* ext_a, Vec3* ext_b);

/// The extent of L over its sightings: the extreme points along L of their back-projected segments (backProjectSegment
/// within [min_depth_m, max_depth_m]); false if none back-projects.
bool extentOnSightings(const Vec6& L, const std::vector<LineSighting>& sightings, double min_depth_m,
                       double max_depth_m, Vec3* a, Vec3* b);

/// Minimises the robustified endpoint distances of the sightings over the line (Plücker L_W, LineManifold update),
/// starting from *L_W. Writes the result and returns true only if it lowers the mean endpoint distance.
bool refineLine(const std::vector<LineSighting>& sightings, const LineRefinementOptions& options, Vec6* L_W);

/// Predicted standard deviation of a map segment's endpoints a, b off the true line, metres: the line's 4x4
/// covariance from its sightings with the poses held (Gauss-Newton information J^T J of the endpoint distances, each
/// with standard deviation pixel_sigma), propagated to each endpoint's displacement across the line; the larger of
/// the two RMS displacements. Infinite when the sightings do not constrain all four degrees of freedom.
double lineEndpointSigmaM(const Vec6& L_W, const std::vector<LineSighting>& sightings, const Vec3& a, const Vec3& b,
                          double focal_px, double pixel_sigma);

}  // namespace linnet
