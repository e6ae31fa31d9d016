// Point triangulation from calibrated views (normalised image coordinates, z = 1 plane).
//
// Views are given as camera poses T_W_C (camera in world, DESIGN A3) and undistorted normalised observations
// uv. The linear method is the homogeneous DLT of Hartley & Zisserman, "Multiple View Geometry", 2nd ed.,
// sec. 12.2; an optional Gauss-Newton refinement minimises the reprojection error in normalised coordinates.
#pragma once

#include <string>
#include <vector>

#include "linnet/core/pose.h"
#include "linnet/core/types.h"

namespace linnet {

/// Acceptance thresholds for a triangulated point (used by triangulateChecked).
struct TriangulationOptions {
  double min_depth_m = 0.1;        // metres, in every view
  double max_depth_m = 80.0;       // metres, in every view
  double min_parallax_deg = 0.5;   // degrees, largest angle between any two viewing rays
  double max_reprojection = 0.01;  // normalised units (about 4.6 px at f = 458), mean over the views
  int refine_iterations = 5;       // Gauss-Newton steps after the DLT (0 = DLT only)

  template <class V>
  void visit(V& v) {
    v("min_depth_m", min_depth_m, "minimum depth in every view, m", 1e-6, 1e3);
    v("max_depth_m", max_depth_m, "maximum depth in every view, m", 1e-3, 1e6);
    v("min_parallax_deg", min_parallax_deg, "minimum parallax between viewing rays, deg", 0.0, 90.0);
    v("max_reprojection", max_reprojection, "maximum mean reprojection error, normalised units", 1e-6, 1.0);
    v("refine_iterations", refine_iterations, "Gauss-Newton refinement steps", 0, 100);
  }
};

/// Outcome of triangulateChecked.
enum class TriangulationStatus { kOk, kTooFewViews, kDegenerate, kLowParallax, kBadDepth, kHighError };
const char* toString(TriangulationStatus s);

/// Linear triangulation from n >= 2 views by SVD of the stacked 2n x 4 DLT system (rows normalised to unit
/// length). Returns false for fewer than two views, a point at infinity or a non-finite result. Throws
/// UsageError if the two vectors differ in size. Does not check depths: use allDepthsPositive().
bool triangulateDlt(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, Vec3* p_W);

/// Two-view triangulation (DLT on the two views). `parallax_rad` (may be nullptr) receives the angle between
/// the two viewing rays in radians, whatever the return value.
bool triangulateTwoView(const Pose& T_W_C0, const Vec2& uv0, const Pose& T_W_C1, const Vec2& uv1, Vec3* p_W,
                        double* parallax_rad);

/// Angle (radians) between the viewing rays of uv0 in camera 0 and uv1 in camera 1, both expressed in the
/// world.
double rayParallaxRad(const Pose& T_W_C0, const Vec2& uv0, const Pose& T_W_C1, const Vec2& uv1);

/// Largest pairwise ray parallax over all views (radians); 0 for fewer than two views.
double maxParallaxRad(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv);

/// Depth (z) of the world point p_W in camera T_W_C.
double depthInCamera(const Pose& T_W_C, const Vec3& p_W);

/// True if the point's depth lies in [min_depth, max_depth] in every view.
bool allDepthsPositive(const std::vector<Pose>& T_W_C, const Vec3& p_W, double min_depth = 1e-6,
                       double max_depth = 1e12);

/// Mean reprojection error over the views, in normalised units (infinity if behind a camera).
double meanReprojectionError(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, const Vec3& p_W);

/// Gauss-Newton refinement of p_W minimising the normalised reprojection error over all views (a few steps,
/// stops when the step is tiny or the cost does not decrease). Returns false (and leaves p_W unchanged) if
/// the point is behind a camera at the start or the normal equations are singular.
bool refinePoint(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv, Vec3* p_W,
                 int max_iterations = 5);

/// DLT + refinement + every acceptance check of `options`. p_W is written only when the status is kOk.
TriangulationStatus triangulateChecked(const std::vector<Pose>& T_W_C, const std::vector<Vec2>& uv,
                                       const TriangulationOptions& options, Vec3* p_W);

}  // namespace linnet
