// Options of the sliding-window stereo-inertial estimator (DESIGN B1). One struct per concern, gathered in
// EstimatorOptions; every field has a default, a unit and a range in visit().
#pragma once

#include <string>

#include "linnet/core/options.h"
#include "linnet/estimator/line_map_curation.h"
#include "linnet/imu/gravity_alignment.h"

namespace linnet {

/// IMU-aided keyframe selection (thesis ch. 4, "keyframe selection"; DESIGN B1).
struct KeyframeOptions {
  double min_parallax_px = 10.0;       // rotation-compensated mean parallax to the last keyframe, pixels
  double static_translation_m = 0.05;  // IMU-integrated translation below this = static or pure rotation, m
  double max_rotation_deg = 20.0;      // in the small-translation case a keyframe also needs rotation below this, deg
  int min_tracked = 40;                // fewer points tracked from the last keyframe forces a keyframe
  double max_gap_s = 2.0;              // a keyframe at least this often (bounds a preintegration's length), s

  template <class V>
  void visit(V& v) {
    v("min_parallax_px", min_parallax_px, "keyframe if mean parallax exceeds this, pixels", 0.0, 1000.0);
    v("static_translation_m", static_translation_m, "translation below this = static / pure rotation, m", 0.0, 100.0);
    v("max_rotation_deg", max_rotation_deg, "small-translation keyframes need rotation below this, deg", 0.0, 180.0);
    v("min_tracked", min_tracked, "fewer tracked points forces a keyframe", 0, 100000);
    v("max_gap_s", max_gap_s, "longest time between keyframes, s", 0.05, 1000.0);
  }
};

/// Stereo-inertial initialisation (DESIGN B1, thesis ch. 5).
struct InitOptions {
  double gravity_window_s = 0.5;     // IMU before the first frame averaged for gravity alignment, s
  StaticDetectionOptions at_rest;    // when the IMU window counts as "at rest" (static initialisation)
  int moving_frames = 8;             // frames collected by PnP before the gyro bias / velocity solve when moving
  int min_points = 15;               // stereo-triangulated points needed to start (and for each PnP)
  double max_pnp_error_px = 3.0;     // RMS reprojection error that a PnP pose must reach, pixels
  int solver_iterations = 10;        // Ceres iterations of the first solve after a moving initialisation (at least
                                     // solver.max_num_iterations)
  // The prior that starts a window (initial_prior.h): gauge + what the initialiser knows.
  double prior_position_m = 1e-3;    // first position (gauge), m
  double prior_yaw_deg = 0.05;       // first yaw (gauge), deg
  double prior_velocity_static = 0.02;  // velocity of a static start, m/s
  double prior_velocity_reinit = 0.2;   // velocity carried over from the last good state, m/s
  double prior_acc_bias = 0.2;       // accelerometer bias, m/s^2
  double prior_gyr_bias = 0.01;      // gyroscope bias, rad/s

  template <class V>
  void visit(V& v) {
    v("gravity_window_s", gravity_window_s, "IMU averaged for gravity alignment, s", 0.01, 10.0);
    v.section("at_rest", at_rest);
    v("moving_frames", moving_frames, "frames before the moving initialisation solve", 3, 100);
    v("min_points", min_points, "stereo points needed to initialise", 4, 10000);
    v("max_pnp_error_px", max_pnp_error_px, "largest RMS PnP reprojection error, pixels", 0.1, 100.0);
    v("solver_iterations", solver_iterations, "Ceres iterations of the first solve after a moving start", 1, 1000);
    v("prior_position_m", prior_position_m, "first-frame position prior sigma (gauge), m", 1e-9, 1e3);
    v("prior_yaw_deg", prior_yaw_deg, "first-frame yaw prior sigma (gauge), deg", 1e-9, 180.0);
    v("prior_velocity_static", prior_velocity_static, "static-start velocity prior sigma, m/s", 1e-6, 100.0);
    v("prior_velocity_reinit", prior_velocity_reinit, "re-initialisation velocity prior sigma, m/s", 1e-6, 100.0);
    v("prior_acc_bias", prior_acc_bias, "accelerometer bias prior sigma, m/s^2", 1e-6, 100.0);
    v("prior_gyr_bias", prior_gyr_bias, "gyroscope bias prior sigma, rad/s", 1e-6, 100.0);
  }
};

/// Failure detection -> reset and re-initialisation from the last good state.
struct FailureOptions {
  int min_tracked = 8;               // fewer landmarks seen in the newest frame = failure
  double max_velocity = 10.0;        // m/s
  double max_acc_bias = 2.5;         // m/s^2
  double max_gyr_bias = 1.0;         // rad/s
  double max_jump_m = 2.0;           // largest position change of the newest frame in one solve, m
  double max_jump_deg = 30.0;        // largest rotation change of the newest frame in one solve, deg
  double max_dead_reckoning_s = 2.0; // after a failure, IMU-only output for at most this long, then kLost, s

  template <class V>
  void visit(V& v) {
    v("min_tracked", min_tracked, "tracked landmarks below this = failure", 0, 10000);
    v("max_velocity", max_velocity, "speed above this = failure, m/s", 0.1, 1000.0);
    v("max_acc_bias", max_acc_bias, "accelerometer bias norm above this = failure, m/s^2", 0.01, 100.0);
    v("max_gyr_bias", max_gyr_bias, "gyroscope bias norm above this = failure, rad/s", 0.001, 100.0);
    v("max_jump_m", max_jump_m, "position jump in one solve above this = failure, m", 0.01, 1000.0);
    v("max_jump_deg", max_jump_deg, "rotation jump in one solve above this = failure, deg", 0.1, 180.0);
    v("max_dead_reckoning_s", max_dead_reckoning_s, "IMU-only output after a failure at most this long, s", 0.0,
      100.0);
  }
};

/// Gaps in the IMU stream (dropped samples, a paused driver). A step longer than `gap_periods` sample periods is
/// bridged by linear interpolation of its end samples, with the unknown motion in between modelled as an extra
/// acceleration / angular-rate noise of `acc_sigma` / `gyr_sigma` over the gap (PreintegrationOptions::gap_*). A gap
/// longer than `max_bridge_s` is not integrated: the window is dropped and the estimator re-initialises after it
/// (counted as a re-initialisation) from the last good pose.
struct ImuGapOptions {
  double gap_periods = 3.0;   // a step longer than this many sample periods (1 / imu.rate_hz) is a gap
  double max_bridge_s = 0.5;  // longest gap bridged by interpolation, s; longer: re-initialise after it
  double acc_sigma = 2.0;     // std of the unknown acceleration over a bridged gap, m/s^2
  double gyr_sigma = 0.5;     // std of the unknown angular rate over a bridged gap, rad/s

  template <class V>
  void visit(V& v) {
    v("gap_periods", gap_periods, "a step longer than this many IMU sample periods is a gap", 1.0, 1000.0);
    v("max_bridge_s", max_bridge_s, "longest IMU gap bridged by interpolation (longer: re-initialise), s", 0.0,
      10.0);
    v("acc_sigma", acc_sigma, "unknown acceleration over a bridged gap, m/s^2", 0.0, 100.0);
    v("gyr_sigma", gyr_sigma, "unknown angular rate over a bridged gap, rad/s", 0.0, 100.0);
  }
};

/// Back-end solver and measurement model.
struct SolverOptions {
  std::string engine = "schur_lm";   // per-frame window solve: "schur_lm" (Linnet's Levenberg-Marquardt with the
                                     // landmarks eliminated by Schur complement, schur_lm_solver.h) | "ceres" (Ceres
                                     // with trust_region / linear_solver below)
  int max_num_iterations = 1;        // solver iterations per frame (the IMU prediction is a good start). With the
                                     // Huber thresholds at 0.5 one step is as good as up to three (nine hard / low-
                                     // texture replays: loop-corrected / odometry APE means 0.0101 / 0.0210 m
                                     // against 0.0099 / 0.0210 m) for 8-18 % less CPU; at 1.0 the second step
                                     // carried MH_01 hall (0.0109 -> 0.0159 m with one)
  double max_solver_time_s = 0.5;    // solver wall-time bound per frame, s (must not bind for bit-identical runs)
  double function_tolerance = 1e-2;  // schur_lm: the frame's iterations stop once a step lowers the cost by less than
                                     // this share of it (the next would lower it less still). 1e-6 -> 1e-2: one-core
                                     // CPU real-time factor on MH_01 hall hard 0.276 -> 0.256, APE on 9 hard and
                                     // low-texture replays within 1.4 % (mean 0.0340 -> 0.0342 m)
  int line_iterations = 5;           // schur_lm: damped Gauss-Newton iterations of each line alone (poses held)
                                     // before the frame's first step and after each accepted one (0: none). The
                                     // joint steps move lines slowly (landmark_damping), so 3 steps left them
                                     // unconverged and the newest pose jittered: V1_02 room, RMS change of the
                                     // position error between frames 1.54 -> 0.79 mm (points only 0.80), APE with
                                     // loop closure 0.0131 -> 0.0099 m; one-core CPU +5 %
  bool calibration_on_keyframes = true;  // while the calibration (extrinsics, cam1's correction, time offset) is
                                         // estimated, only the solves of keyframes move it; the other solves hold
                                         // it (a non-keyframe leaves the window without entering the prior, and
                                         // held blocks leave the system: the calibration phase's extra back-end
                                         // cost falls to about a quarter)
  bool lines_on_keyframes = false;       // schur_lm: line landmarks move only in the solves of keyframes (held in
                                         // the others, as the calibration, and not iterated alone). Nine hard /
                                         // low-texture replays, two samples: -5 % CPU, but loop-corrected APE
                                         // +4 % on the mean (0.01691 -> 0.01757 m; V1_02 room, V2_02 room and
                                         // MH_01 hall hard worse in both samples), so it stays off
  std::string trust_region = "dogleg";   // Ceres: "levenberg_marquardt" | "dogleg"
  std::string linear_solver = "dense_schur";  // Ceres: "dense_schur" | "sparse_normal_cholesky"
  double focal_length = 460.0;       // pixels per normalised unit: sqrt_info = focal_length / pixel_sigma
  double pixel_sigma = 1.5;          // std of a point observation, pixels
  double huber_px = 0.5;             // Huber threshold on the whitened point residual (units of pixel_sigma). 1.0 ->
                                     // 0.5 (points and lines): nine hard / low-texture replays' odometry APE mean
                                     // 0.0235 -> 0.0210 m, better on each; loop-corrected 0.0104 -> 0.0101 m
  double outlier_px = 3.0;           // landmarks whose mean reprojection error exceeds this are removed, pixels
  double min_depth_m = 0.1;          // triangulated depth range, m
  double max_depth_m = 40.0;
  double min_triangulation_deg = 1.0;  // smallest ray angle for a multi-view (non-stereo) triangulation, deg
  int min_observations = 2;          // window frames a landmark must be seen in to enter a solve (>= 2)
  bool right_residuals_all_frames = false;  // host cam0 -> cam1 residuals in every observing frame (false: only
                                            // the host frame's left-right residual uses cam1; halves the residuals,
                                            // full V1_02 replay: APE 19 -> 15 mm, back-end CPU -25%)

  template <class V>
  void visit(V& v) {
    v.choice("engine", engine, "per-frame window solver", {"schur_lm", "ceres"});
    v("max_num_iterations", max_num_iterations, "solver iterations per frame", 1, 1000);
    v("max_solver_time_s", max_solver_time_s, "solver time bound per frame, s", 0.001, 100.0);
    v("function_tolerance", function_tolerance, "relative cost decrease that ends the frame's iterations", 0.0, 1.0);
    v("line_iterations", line_iterations, "iterations of each line alone around the frame's steps", 0, 100);
    v("calibration_on_keyframes", calibration_on_keyframes,
      "estimate the calibration only in the solves of keyframes (held in the others)");
    v("lines_on_keyframes", lines_on_keyframes, "line landmarks move only in the solves of keyframes");
    v.choice("trust_region", trust_region, "Ceres trust-region strategy", {"levenberg_marquardt", "dogleg"});
    v.choice("linear_solver", linear_solver, "Ceres linear solver", {"dense_schur", "sparse_normal_cholesky"});
    v("focal_length", focal_length, "pixels per normalised unit", 1.0, 10000.0);
    v("pixel_sigma", pixel_sigma, "point observation std, pixels", 0.01, 100.0);
    v("huber_px", huber_px, "Huber threshold, whitened units", 0.01, 100.0);
    v("outlier_px", outlier_px, "mean reprojection error limit, pixels", 0.1, 1000.0);
    v("min_depth_m", min_depth_m, "nearest triangulated depth, m", 0.001, 100.0);
    v("max_depth_m", max_depth_m, "farthest triangulated depth, m", 0.1, 100000.0);
    v("min_triangulation_deg", min_triangulation_deg, "smallest multi-view ray angle, deg", 0.0, 90.0);
    v("min_observations", min_observations, "frames a landmark must be seen in to enter a solve", 2, 1000);
    v("right_residuals_all_frames", right_residuals_all_frames, "cam1 residuals in every observing frame");
  }
};

/// Line landmarks in the window (DESIGN B1 "Line parameterisation", "Optimisation"; thesis ch. 3-4; patent for
/// the point / line weighting).
struct LineOptions {
  bool enabled = true;                // use the front-end's lines (when pipeline.use_lines delivers them)
  double pixel_sigma = 1.5;           // std of an endpoint-to-line distance, pixels
  std::string loss = "huber";         // robust loss of the line residuals: huber | cauchy
  double huber_px = 0.5;              // threshold of that loss on the whitened line residual (units of pixel_sigma;
                                      // 0.5 with the points', see SolverOptions::huber_px)
  double outlier_px = 3.0;            // lines whose mean endpoint distance exceeds this after a solve are removed
                                      // (thesis: 3 px), pixels
  double max_observation_px = 5.0;    // one sighting (a frame's cam0 or cam1 segment) whose mean endpoint distance
                                      // exceeds this after a solve is dropped from its line, which stays (a mismatched
                                      // frame of a good track); about the 99.9 % bound of a 2-D residual at
                                      // pixel_sigma 1.5 px, pixels
  double min_plane_angle_deg = 1.0;   // triangulation: smallest angle between the two back-projection planes (stereo
                                      // pair or two frames; small = line along the baseline / motion), deg
  double min_view_angle_deg = 5.0;    // a line seen within this angle of end-on (direction vs the viewing ray of its
                                      // midpoint, newest frame) is degenerate and removed, deg
  double min_depth_m = 0.1;           // depth range of the back-projected endpoints in every observing camera, m
  double max_depth_m = 30.0;
  double max_length_m = 20.0;         // longest triangulated segment, m
  double max_extent_gap_m = 0.5;      // the newest observation's back-projected segment farther than this from the
                                      // line's extent (drifted off / mismatched track): line removed, m
  int min_observations = 2;           // window frames a line must be seen in to enter a solve (>= 2)
  bool right_residuals = true;        // cam1 residuals where the line is matched in the right image
  bool marginalise = true;            // when the oldest keyframe leaves, its lines' residuals go into the prior (the
                                      // thesis' strategy, lines dropped from it as landmarks); false: its line
                                      // observations are only dropped
  bool map_refine = true;             // a line leaving the window for the map is re-estimated on every observation of
                                      // its life at the frames' final poses (line_map_refinement.h)
  bool reidentify = true;             // a new track whose first sighting lies on the projection of a window line not
                                      // seen in that frame (the tracker lost the line and found it again under a new
                                      // id) continues that line: longer tracks, one landmark per line
  double reid_px = 2.0;               // re-identification: both endpoints within this of the line's projection, in
                                      // cam0 and (if matched) cam1, at the frame's predicted pose, pixels
  bool reid_map = false;              // map lines (that left the window) in front of the camera are candidates too:
                                      // found again, they come back into the window with their sightings
  double reid_ambiguity = 2.0;        // a second window line within reid_ambiguity x reid_px of the sighting (a
                                      // parallel edge nearby): ambiguous, no re-identification
  bool weighting = false;             // patent point / line weighting per frame (see below); off: it did not help
  int weighting_min_lines = 30;       // more lines than this in a frame: the fixed weights below
  double point_weight = 0.2;          // patent: w_p, w_l (line-dominant in low texture); otherwise the weights
  double line_weight = 0.8;           // follow the counts (n_p, n_l) / (n_p + n_l). Costs are scaled by 2 w
  LineMapOptions map;                 // the published line map: its well-constrained lines (line_map_curation.h)

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "use lines in the estimator when the front-end delivers them");
    v("pixel_sigma", pixel_sigma, "line endpoint distance std, pixels", 0.01, 100.0);
    v.choice("loss", loss, "robust loss of line residuals", {"huber", "cauchy"});
    v("huber_px", huber_px, "threshold of the line residuals' robust loss, whitened units", 0.01, 100.0);
    v("outlier_px", outlier_px, "mean endpoint distance limit, pixels", 0.1, 1000.0);
    v("max_observation_px", max_observation_px, "one sighting's endpoint distance limit (sighting dropped), pixels",
      0.1, 1000.0);
    v("min_plane_angle_deg", min_plane_angle_deg, "smallest back-projection plane angle to triangulate, deg", 0.0,
      90.0);
    v("min_view_angle_deg", min_view_angle_deg, "lines seen closer to end-on are removed, deg", 0.0, 90.0);
    v("min_depth_m", min_depth_m, "nearest endpoint depth, m", 0.001, 100.0);
    v("max_depth_m", max_depth_m, "farthest endpoint depth, m", 0.1, 100000.0);
    v("max_length_m", max_length_m, "longest line segment, m", 0.01, 100000.0);
    v("max_extent_gap_m", max_extent_gap_m, "largest gap of a new observation to the line's extent, m", 0.0,
      1000.0);
    v("min_observations", min_observations, "frames a line must be seen in to enter a solve", 2, 1000);
    v("right_residuals", right_residuals, "cam1 line residuals where matched");
    v("marginalise", marginalise, "lines observed by the leaving keyframe go into the prior");
    v("map_refine", map_refine, "refine lines leaving the window on all their observations");
    v("reidentify", reidentify, "new tracks lying on a window line's projection continue that line");
    v("reid_px", reid_px, "re-identification: largest endpoint distance to the line's projection, pixels", 0.0,
      100.0);
    v("reid_map", reid_map, "re-identification also against the map's lines (restored into the window)");
    v("reid_ambiguity", reid_ambiguity, "re-identification: a second line within this factor of reid_px: none", 1.0,
      100.0);
    v("weighting", weighting, "patent point / line weighting per frame");
    v("weighting_min_lines", weighting_min_lines, "lines in a frame above which the fixed weights apply", 0, 100000);
    v("point_weight", point_weight, "point weight w_p with many lines", 0.0, 1.0);
    v("line_weight", line_weight, "line weight w_l with many lines", 0.0, 1.0);
    v.section("map", map);
  }
};

/// How the IMU is weighted. The densities come from the calibration (a Kalibr / EuRoC imu sensor.yaml: the datasheet's
/// white noise); on a multicopter the error in flight is far larger (rotor vibration, airframe motion: the ADIS16448
/// of EuRoC V1_01_easy has about 30x the datasheet's density between 5 and 20 Hz, docs/realism.md). The scales
/// multiply the calibration's values in the preintegration covariance.
struct ImuWeightOptions {
  double noise_density_scale = 5.0;  // multiplies the accelerometer and gyroscope white-noise densities; hard
                                     // V1_01 replay: 1 -> 0.027 m, 3 -> 0.017, 5 -> 0.016, 10 -> 0.017
  double random_walk_scale = 1.0;    // multiplies the bias random-walk densities (3x: 0.027 -> 0.026 m)

  template <class V>
  void visit(V& v) {
    v("noise_density_scale", noise_density_scale, "multiplies the calibration's IMU white-noise densities", 0.01,
      1000.0);
    v("random_walk_scale", random_walk_scale, "multiplies the calibration's bias random-walk densities", 0.01,
      1000.0);
  }
};

/// Online refinement of the camera-IMU extrinsics (factors/pose_wrappers.h): one rigid correction of the stereo rig
/// against the IMU, common to both cameras, estimated in the window with a prior at the calibration.
struct ExtrinsicsOptions {
  bool estimate = true;               // refine the rig's extrinsics online. 9 hard and low-texture replays (held after
                                      // 40 s, below): mean APE 0.0342 -> 0.0334 m, V1_02 hard 0.036 -> 0.029 m on
                                      // seed 0 (0.049 -> 0.042 m on seed 1), V2_01 hard 0.023 -> 0.027 m; README
                                      // "Online calibration"
  double prior_rotation_deg = 0.1;    // prior sigma of the rotation correction (per axis), deg: a Kalibr calibration's
                                      // typical error. 0.5 let early, weakly observed windows move it (synthetic test:
                                      // APE 4.9 vs 3.3 mm; 9 hard replays: mean 0.0355 vs 0.0353 m)
  double prior_translation_m = 0.002; // prior sigma of the translation correction (per axis), m (weakly observable:
                                      // 0.5-10 mm gave the same synthetic APE)
  double estimate_for_s = 40.0;       // > 0: the correction is estimated over this much tracked time in motion, then
                                      // held in the cameras' extrinsics (no cost after that); 0: estimated all along,
                                      // s. Estimated, it costs about 20% CPU (6 more dimensions in each landmark's
                                      // Schur update). 9 replays, mean APE: all along 0.0332 m, 60 s 0.0332, 40 s
                                      // 0.0334; 20 s had not converged (0.0362 then, against 0.0353 all along)
  // cam1 relative to cam0 (a correction S of cam1's pose, cam1 at T_B_R * T_B_C1 * S), refined with the rig and held
  // with it. A disparity bias of a few hundredths of a pixel (relative yaw, principal points) is a scale error of the
  // stereo depths that grows with depth, which the IMU then fights (MH_01 hall hard: 0.45 % scale error).
  bool estimate_stereo = true;        // refine cam1 relative to cam0 too (stereo rigs only). 9 hard and low-texture
                                      // replays with loop closure: mean APE 0.0237 -> 0.0190 m (MH_01 hall hard
                                      // 0.0307 -> 0.0173 m); exact calibrations lose a little (V2_02 lowtex +6 %)
  double prior_stereo_rotation_deg = 0.02;   // prior sigma of cam1's rotation correction (per axis), deg: a stereo
                                             // calibration's 0.01 deg with 0.1 px principal points per camera
  double prior_stereo_translation_m = 1e-4;  // prior sigma of cam1's translation correction (per axis), m
  double stereo_from_s = 10.0;        // cam1's correction is estimated from this much tracked time in motion on
                                      // until the rig's hold, s: the first windows see it weakly and let it take up
                                      // other errors (18 s low-texture replay with an exact calibration: APE 0.0235 m
                                      // without it, 0.0276 from the start, 0.0241 from 5 s, 0.0225 from 10 s)

  template <class V>
  void visit(V& v) {
    v("estimate", estimate, "refine the camera-IMU extrinsics (common to both cameras) online");
    v("estimate_stereo", estimate_stereo, "also refine cam1 relative to cam0 (with the rig, held with it)");
    v("prior_stereo_rotation_deg", prior_stereo_rotation_deg, "prior sigma of cam1's rotation correction, deg", 1e-6,
      30.0);
    v("prior_stereo_translation_m", prior_stereo_translation_m, "prior sigma of cam1's translation correction, m",
      1e-9, 1.0);
    v("stereo_from_s", stereo_from_s, "tracked time in motion after which cam1's correction is estimated, s", 0.0,
      1e9);
    v("prior_rotation_deg", prior_rotation_deg, "prior sigma of the extrinsic rotation correction, deg", 1e-6, 30.0);
    v("prior_translation_m", prior_translation_m, "prior sigma of the extrinsic translation correction, m", 1e-9,
      1.0);
    v("estimate_for_s", estimate_for_s, "tracked time in motion over which the extrinsics are refined, then held (0: always), s",
      0.0, 1e9);
  }
};

/// Online estimation of the camera-to-IMU time offset t_d (factors/pose_wrappers.h, TimeShiftedFactor): camera stamps
/// are taken as the capture time on the IMU clock plus t_d (Kalibr's timeshift_cam_imu is -t_d).
struct TimeOffsetOptions {
  bool estimate = true;     // estimate t_d online. Hard replays with a 3 ms offset: recovered within 0.4 ms on 8 of
                            // 9 (README); mean APE over them 0.0376 -> 0.0368 m; +20% CPU in the window solve
  double initial_ms = 0.0;  // t_d to start from (and the prior's mean), ms
  double prior_ms = 5.0;    // prior sigma of t_d, ms
  double estimate_for_s = 20.0;  // t_d is estimated over this much tracked time in motion, then held (the residuals keep the
                                 // shift, without the extra block's cost: about a fifth of the CPU of a run); 0:
                                 // estimated all along. Hard replays: converged within 0.3 ms of 3 ms by then, s

  template <class V>
  void visit(V& v) {
    v("estimate", estimate, "estimate the camera-to-IMU time offset online");
    v("initial_ms", initial_ms, "camera-to-IMU time offset to start from (camera stamp - capture time), ms", -1000.0,
      1000.0);
    v("prior_ms", prior_ms, "prior sigma of the camera-to-IMU time offset, ms", 1e-6, 1000.0);
    v("estimate_for_s", estimate_for_s, "tracked time in motion over which the offset is estimated, then held (0: always), s",
      0.0, 1e9);
  }
};

/// Zero-velocity update: when the IMU says "at rest", the estimated speed is small and the tracked points have not
/// moved since the previous frame, the newest frame's velocity gets a zero prior and its pose a no-motion prior to
/// the previous window frame (as OpenVINS' ZUPT, with an image-motion check). Without it, at rest
/// the pose follows the frame-to-frame noise of the visual measurements (lines' endpoints on the real V1_01 snippet:
/// median 0.22 px but 10% above 1.2 px between consecutive frames).
struct ZeroVelocityOptions {
  bool enabled = true;              // detect rest and add the zero-velocity prior
  double window_s = 0.5;            // IMU before the frame that must pass the at-rest test (init.at_rest), s
  double max_motion_px = 0.5;       // median image motion of the points tracked from the previous frame, pixels
  int min_points = 20;              // fewer points tracked from the previous frame: no decision (no prior)
  double max_speed = 0.05;          // the frame's predicted speed must be below this, m/s: far points barely move
                                    // in the image when the body glides at constant speed (MH_01 hall, hard replay:
                                    // APE 0.026 -> 0.121 m without this test)
  double velocity_sigma = 0.01;     // sigma of the zero-velocity prior, m/s
  double position_sigma_m = 0.001;  // no-motion prior to the previous window frame: position sigma, m
  double rotation_sigma_deg = 0.05;  // and rotation sigma, deg

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "zero-velocity prior when at rest (IMU and image motion)");
    v("window_s", window_s, "IMU span tested for rest before each frame, s", 0.05, 10.0);
    v("max_motion_px", max_motion_px, "largest median point motion from the previous frame at rest, pixels", 0.0,
      100.0);
    v("min_points", min_points, "points tracked from the previous frame needed to decide", 1, 100000);
    v("max_speed", max_speed, "largest predicted speed of a frame at rest, m/s", 0.0, 100.0);
    v("velocity_sigma", velocity_sigma, "sigma of the zero-velocity prior, m/s", 1e-6, 10.0);
    v("position_sigma_m", position_sigma_m, "no-motion prior to the previous frame at rest: position sigma, m", 1e-9,
      10.0);
    v("rotation_sigma_deg", rotation_sigma_deg, "no-motion prior at rest: rotation sigma, deg", 1e-9, 180.0);
  }
};

struct EstimatorOptions {
  int window_size = 5;               // keyframes in the window (plus the newest frame). Five samples of the nine
                                     // hard / low-texture replays: 5 vs 6 gives APE -2.0 % loop-corrected, -3.2 %
                                     // odometry, for -3.2 % CPU; 6 vs 7 -1.6 / -3.8 %, -3.8 % instructions
  SolverOptions solver;
  KeyframeOptions keyframe;
  InitOptions init;
  FailureOptions failure;
  LineOptions lines;
  ImuWeightOptions imu;
  ImuGapOptions imu_gap;
  ExtrinsicsOptions extrinsics;
  TimeOffsetOptions time_offset;
  ZeroVelocityOptions zero_velocity;

  template <class V>
  void visit(V& v) {
    v("window_size", window_size, "keyframes in the sliding window", 2, 100);
    v.section("imu", imu);
    v.section("imu_gap", imu_gap);
    v.section("solver", solver);
    v.section("keyframe", keyframe);
    v.section("init", init);
    v.section("failure", failure);
    v.section("lines", lines);
    v.section("extrinsics", extrinsics);
    v.section("time_offset", time_offset);
    v.section("zero_velocity", zero_velocity);
  }
};

}  // namespace linnet
