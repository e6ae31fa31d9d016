// What the loop closer keeps of a keyframe to recognise its place later, and the geometric verification of a loop.
// A keyframe keeps ORB descriptors (Rublee et al., "ORB: an efficient alternative to SIFT or SURF", ICCV 2011) of
// two sets: its tracked corners with their stereo-triangulated positions (3D), and many more FAST corners of its
// left image (2D only). The tracked set alone repeats poorly between two visits (a tracker re-detects corners only
// where tracks are missing), so a loop is verified by matching one keyframe's 3D set to the other's dense 2D set and
// solving PnP in RANSAC (as VINS-Mono does with its extra BRIEF corners).
#pragma once

#include <array>
#include <optional>
#include <vector>

#include <opencv2/core.hpp>

#include "linnet/core/frame_observations.h"
#include "linnet/core/map_line.h"
#include "linnet/core/pose.h"
#include "linnet/features/line_lbd.h"
#include "linnet/features/point_detection.h"
#include "linnet/features/line_types.h"

namespace linnet {

class CameraModel;

struct PlaceFeatures {
  std::vector<Vec3> p_C;    // tracked corners with a position: in cam0
  cv::Mat descriptors_3d;   // their ORB descriptors, one 32-byte row each (CV_8U)
  // Every described tracked corner: its track id, descriptor and stereo-triangulated position in cam0 (NaN: none).
  std::vector<std::int64_t> tracked_ids;
  cv::Mat tracked_descriptors;
  std::vector<Vec3> tracked_stereo_p_C;
  std::vector<int> tracked_rows;  // each tracked corner's row in uv / descriptors_2d (describePlace)
  std::vector<int> rows_3d;       // each 3D corner's row in uv / descriptors_2d (setPlaceDepths; empty: unknown)
  std::vector<Vec2> uv;     // every described corner (tracked and detected): normalised, undistorted cam0 coordinates
  cv::Mat descriptors_2d;   // their ORB descriptors
  // The keyframe's tracked lines in cam0 (describePlaceLines): track id, normalised undistorted endpoints, LBD
  // descriptor, and the 3D segment in cam0 from the odometry's line landmark (setPlaceLines; NaN: none).
  std::vector<std::int64_t> line_ids;
  std::vector<std::array<Vec2, 2>> line_uv;
  std::vector<LbdDescriptor> line_desc;
  std::vector<std::array<Vec3, 2>> line_p_C;
};

struct PlaceDescription {
  int patch_px = 31;      // ORB patch side, pixels
  int corners = 400;      // FAST corners described besides the tracked ones (strongest first)
  int fast_threshold = 20;
};

/// Describes a keyframe: the tracked corners (`points`, cam0 pixels px0), triangulated where matched in cam1
/// (T_C1_C0: cam0 -> cam1), and the strongest FAST corners of `left`. Corners too close to the border for the patch
/// are left out. `found` (may be null): the FAST corners of `left` already found, used instead of a new search when
/// their threshold is options.fast_threshold (the same corners).
PlaceFeatures describePlace(const cv::Mat& left, const CameraModel& cam0, const std::vector<PointObservation>& points,
                            const Pose& T_C1_C0, const PlaceDescription& options, const FastCorners* found = nullptr);

struct PlaceMatchOptions {
  int max_hamming = 64;      // bits
  double match_ratio = 0.8;  // best / second best
  int min_inliers = 25;
  double ransac_px = 2.0;    // pixels
  double focal_px = 458.0;   // converts ransac_px to normalised units
  // Refine the one-way PnP on both keyframes' 3D corners: the first's seen in the second and the second's in the
  // first, jointly, so that neither keyframe's landmark errors alone set the relative pose.
  bool two_way = false;
  // Guided matching when descriptor matching alone fails: with a predicted relative pose (prior_T_Cold_Cnew), each
  // 3D corner is matched to the corners within guided_radius_px of its projection (0: off). Low-texture keyframes
  // keep too few 3D corners for the ratio test over the whole image to find enough pairs.
  std::optional<Pose> prior_T_Cold_Cnew;
  double guided_radius_px = 0.0;
  // With a prior, when points alone find no loop: the lines' 3D segments matched to the other keyframe's lines
  // around their projections (direction within line_max_angle_deg, LBD distance line_max_hamming) and the pose
  // refined from the prior on points and lines together (matchPlacesWithLines).
  bool use_lines = false;
  int line_max_hamming = 70;        // bits of 256
  double line_max_angle_deg = 5.0;  // degrees
};

/// How a loop was verified: descriptor matching over the whole image, matching guided by the predicted relative pose,
/// or points and lines together around that prediction (matchPlacesWithLines).
enum class PlaceMatchMethod { kDescriptors, kGuided, kLines };

/// "descriptors", "guided" or "lines" (loops.csv, the Python API).
const char* placeMatchMethodName(PlaceMatchMethod method);

struct PlaceMatch {
  bool ok = false;
  PlaceMatchMethod method = PlaceMatchMethod::kDescriptors;
  int matches = 0;           // descriptor matches that passed the ratio test
  int inliers = 0;           // PnP RANSAC inliers
  int reverse_inliers = 0;   // with two_way: the other keyframe's 3D corners that agree with the PnP and were used
  Pose T_Cold_Cnew;          // the new keyframe's cam0 in the old one's cam0
  // Covariance of T_Cold_Cnew for the perturbation R <- exp(dtheta) R, t <- t + dt (order dtheta, dt; rad, m): the
  // PnP's Gauss-Newton inverse scaled by its inliers' residual variance (which holds the old landmarks' errors too).
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

/// Rebuilds p_C / descriptors_3d of the tracked corners: p_W_tracked[i] (the odometry's landmark position of
/// tracked_ids[i], NaN if none; seen from T_W_C, the camera pose of the same estimate) where finite and in front,
/// else the stereo position.
void setPlaceDepths(const std::vector<Vec3>& p_W_tracked, const Pose& T_W_C, PlaceFeatures* f);

/// Matches the new keyframe's 3D corners to the old keyframe's 2D corners and solves the old camera's pose from
/// those pairs (EPnP in RANSAC, then iterative refinement on the inliers); if that fails, the other way round; if
/// that fails too and a prior pose is given, both again with the pairs of guided matching. Deterministic.
PlaceMatch matchPlaces(const PlaceFeatures& old_kf, const PlaceFeatures& new_kf, const PlaceMatchOptions& options);

/// Adds the keyframe's tracked cam0 lines to its place description, with LBD descriptors computed on `left` (the 3D
/// segments unknown until setPlaceLines). `given` (may be null; else parallel to `lines`): their descriptors as the
/// line tracker computed them on `left`, taken instead.
void describePlaceLines(const cv::Mat& left, const std::vector<LineObservation>& lines, const LbdOptions& lbd,
                        PlaceFeatures* f, const std::vector<LbdDescriptor>* given = nullptr);

/// Sets line_p_C from the odometry's line landmarks (`window_lines`, sorted by id; endpoints in W) seen from T_W_C:
/// each tracked line with a landmark whose both endpoints are in front of the camera.
void setPlaceLines(const std::vector<MapLine>& window_lines, const Pose& T_W_C, PlaceFeatures* f);

/// Loop verification with points and lines around options.prior_T_Cold_Cnew: one keyframe's 3D corners and 3D line
/// segments matched to the other's corners and lines near their predicted projections (guided_radius_px), then the
/// relative pose refined from the prior by robust Gauss-Newton on the point reprojection errors and the distances of
/// the projected segment ends to the matched image lines. A loop needs min_inliers points and lines within ransac_px.
/// The new keyframe's 3D features are tried first, then the old one's. Not ok without a prior.
PlaceMatch matchPlacesWithLines(const PlaceFeatures& old_kf, const PlaceFeatures& new_kf,
                                const PlaceMatchOptions& options);

}  // namespace linnet
