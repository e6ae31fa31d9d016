// Options of the loop closer (loop_closer.h): candidate search, geometric verification and the 4-DoF pose graph.
#pragma once

namespace linnet {

struct LoopOptions {
  bool enabled = true;                 // detect loops among the keyframes and correct the trajectory and map. 9 hard
                                       // and low-texture replays: mean APE 0.0334 -> 0.0237 m, MH_04 hall hard
                                       // 0.0544 -> 0.0285 m (README "Loop closure")
  // Candidate search. The odometry drifts slowly, so a place seen before is looked for around the keyframe's
  // position predicted with the current correction, not in the whole database.
  double min_time_gap_s = 20.0;        // a candidate keyframe is at least this much older, s
  double search_radius_m = 1.0;        // radius around the predicted position, m ...
  double search_radius_per_m = 0.03;   // ... plus this fraction of the path travelled since the candidate
  double max_view_angle_deg = 35.0;    // largest angle between the two keyframes' optical axes, deg
  int max_candidates = 3;              // nearest candidates verified per keyframe
  int min_keyframes_between_loops = 5; // keyframes after an accepted loop before the next is looked for
  double place_reuse_m = 0.3;          // a keyframe within this distance of an older described one (and within
                                       // place_reuse_deg of its view) keeps no description of its own, m (0: keep
                                       // all); bounds the database on long flights over the same space. 0.15 -> 0.3
                                       // (stop 39): 10 min figure-eight 602 -> 505 places, the same 761 loops, APE
                                       // 0.0114 -> 0.0113 m, resident set growth after the first minute 10.0 ->
                                       // 9.3-9.5 %; nine hard / low-texture replays' mean 0.01047 -> 0.01046 m (none
                                       // moved by more than 1.5 %): a place 0.3 m away verifies loops as well (the
                                       // search reaches 1 m and 35 deg)
  double place_reuse_deg = 20.0;       // deg (inside max_view_angle_deg: the older one still verifies loops there).
                                       // 10 min figure-eight: 850 -> 617 places, RSS after 10 min 187 -> 177 MB, APE
                                       // 0.0068 -> 0.0065 m; nine hard / low-texture replays 0.01117 -> 0.01121 m
  bool cull_revisits = true;           // such a revisit that closes no loop is not kept as a pose-graph node either
                                       // (its neighbours are linked directly; its frames take the previous node's
                                       // correction): bounds the graph's memory and solve time on long flights
  double consistent_loop_sigmas = 1.0; // a loop within this many of its edge's sigmas of the corrected graph is added
                                       // without a new solve of the whole graph (0: always solve); the loop edges'
                                       // measured error is about 1.5 sigma RMS
  int solve_window_nodes = 300;        // a loop within full_solve_sigmas solves only the newest this many graph
                                       // nodes, the older ones held (0: always the whole graph); the whole graph is
                                       // solved once more at the end of the stream. A solve of the whole graph
                                       // costs more with every node: 175 ms for 1500 nodes on a 10 min flight
  double full_solve_sigmas = 10.0;     // a loop farther than this many of its edge's sigmas from the corrected graph
                                       // solves the whole graph (a large correction bends all of it). The loops of a
                                       // 10 min figure-eight are within 5 (median 1.9): at 3, 1 in 10 was solved
                                       // whole, 33 s of its 45 s of loop CPU
  // Geometric verification (place_matcher.h).
  int orb_patch_px = 31;               // ORB descriptor patch side, pixels
  int corners = 400;                   // FAST corners described per keyframe besides the tracked ones
  int fast_threshold = 20;             // their FAST threshold
  int stored_corners = 200;            // of those, the strongest kept in the database's copy of a place (a new
                                       // keyframe is matched with all of them); < 0: all. A place is mostly its
                                       // corners (19 of its 25 KB at 400: 470 corners at 40 bytes). 400 -> 200,
                                       // five KLT stops of the nine hard / low-texture replays: loop-corrected mean
                                       // 0.01139 -> 0.01141 m (each replay -2.0 to +4.5 %, within its spread), the
                                       // odometry the same; 10 min figure-eight: places 12.1 -> 9.8 MB, resident
                                       // set growth after the first minute +10.8 -> +10.0 %
  int max_hamming = 64;                // largest descriptor distance of a match, bits (of 256)
  double match_ratio = 0.8;            // best / second-best descriptor distance
  int min_inliers = 15;                // PnP RANSAC inliers for a loop. Low-texture keyframes have 50-70 3D corners and
                                       // their true loops 15-28 inliers: 25 found none there. 10 replays (stop 23):
                                       // mean APE 0.0197 -> 0.0169 m, V1_02 lowtex 0.0375 -> 0.0240 m (1 loop), V2_02
                                       // lowtex 0.0323 -> 0.0260 m; textured replays close about twice as many loops
  double ransac_px = 2.0;              // PnP RANSAC reprojection threshold, pixels
  bool two_way_pnp = true;             // refine the PnP on both keyframes' 3D corners (each seen in the other)
  double guided_radius_px = 25.0;      // when descriptor matching finds no loop: match each 3D corner to the corners
                                       // within this radius of where the corrected odometry projects it, pixels
                                       // (0: off)
  bool use_lines = true;               // when points find no loop either way, verify it with points and lines
                                       // together (the keyframes' tracked lines, LBD-described; needs the guided
                                       // radius): low-texture keyframes keep few 3D corners but many lines
  int line_max_hamming = 70;           // LBD distance of a line match, bits of 256
  double line_max_angle_deg = 5.0;     // direction difference of a line match from its predicted projection, deg
  double max_yaw_change_deg = 30.0;    // the loop's yaw correction must be smaller, deg
  // Pose graph (pose_graph.h): x, y, z and yaw per keyframe; roll and pitch stay the odometry's (IMU-observable).
  int sequential_edges = 4;            // odometry edges from each keyframe to the previous ones
  double odometry_sigma_m = 0.005;     // odometry edge sigma, m ...
  double odometry_sigma_per_m = 0.01;  // ... plus this fraction of the edge length
  double odometry_sigma_yaw_deg = 0.05;  // odometry edge yaw sigma, deg
  double loop_sigma_m = 0.01;          // loop edge sigma, m (measured against the truth on MH_01 hall hard and
                                       // a figure-eight replay: 1.5 cm RMS, 0.2 deg; 0.03 m / 0.5 deg gave a mean
                                       // of 0.0245 m on the 9 replays)
  double loop_sigma_yaw_deg = 0.2;     // loop edge yaw sigma, deg
  double loop_pnp_sigma_scale = 1.5;   // > 0: a loop edge's sigmas are at least this times the PnP's own (its
                                       // covariance's largest position / rotation standard deviation), so that a
                                       // loop verified on few or distant points weighs less; 0: the fixed sigmas.
                                       // MH_01 hall, 38 loops against the truth: errors 1.9 cm RMS (up to 5 cm, on
                                       // 15-17 inliers), 1.4-1.5 x the PnP's sigma per axis (the old keyframe's
                                       // landmark errors are correlated, the residual variance does not see that)
  int full_weight_inliers = 25;        // a loop verified on fewer PnP inliers n gets its edge's sigmas multiplied by
                                       // full_weight_inliers / n (0: off). Against the truth (nine hard and
                                       // low-texture replays, 460 loops), the error over the sigma was 1.91 RMS below
                                       // 20 inliers, 1.61 at 20-24, 1.24 at 25-29 and 1.02 from 30 (8 % beyond 3
                                       // sigmas below 20): few inliers miss more than the PnP covariance says (the
                                       // old keyframe's correlated landmark errors). With it: 1.25 / 1.37 / 1.24 / 1.01
  double loop_huber = 0.0;             // Huber threshold of a loop edge, sigmas (0: none; loops are gated by
                                       // verification and by agreement with the corrected odometry instead)
  int max_iterations = 30;             // Levenberg-Marquardt iterations per pose-graph solve

  template <class V>
  void visit(V& v) {
    v("enabled", enabled, "detect loops and correct the trajectory and map (4-DoF pose graph)");
    v("min_time_gap_s", min_time_gap_s, "a loop candidate is at least this much older, s", 0.0, 1e6);
    v("search_radius_m", search_radius_m, "candidate search radius around the predicted position, m", 0.01, 1e3);
    v("search_radius_per_m", search_radius_per_m, "added search radius per metre travelled since the candidate", 0.0,
      1.0);
    v("max_view_angle_deg", max_view_angle_deg, "largest angle between the optical axes of a loop, deg", 1.0, 180.0);
    v("max_candidates", max_candidates, "nearest candidates verified per keyframe", 1, 100);
    v("place_reuse_m", place_reuse_m, "a keyframe this close to an older described one keeps no description, m", 0.0,
      100.0);
    v("place_reuse_deg", place_reuse_deg, "and within this view angle of it, deg", 0.0, 180.0);
    v("cull_revisits", cull_revisits, "such a revisit without a loop is not kept as a pose-graph node");
    v("consistent_loop_sigmas", consistent_loop_sigmas,
      "no graph solve for a loop within this many edge sigmas of the corrected graph (0: always)", 0.0, 100.0);
    v("solve_window_nodes", solve_window_nodes,
      "a loop within full_solve_sigmas solves only the newest this many graph nodes (0: the whole graph)", 0,
      100000000);
    v("full_solve_sigmas", full_solve_sigmas, "a loop farther than this many edge sigmas solves the whole graph", 0.0,
      1e6);
    v("min_keyframes_between_loops", min_keyframes_between_loops, "keyframes after a loop before the next search",
      0, 100000);
    v("orb_patch_px", orb_patch_px, "ORB descriptor patch side, pixels", 7, 101);
    v("corners", corners, "FAST corners described per keyframe besides the tracked ones", 0, 100000);
    v("fast_threshold", fast_threshold, "FAST threshold of those corners", 1, 255);
    v("stored_corners", stored_corners,
      "of those, the strongest kept in the database's copy of a place (-1: all)", -1, 100000);
    v("max_hamming", max_hamming, "largest descriptor distance of a match, bits", 1, 256);
    v("match_ratio", match_ratio, "best / second-best descriptor distance", 0.1, 1.0);
    v("min_inliers", min_inliers, "PnP RANSAC inliers for a loop", 6, 100000);
    v("ransac_px", ransac_px, "PnP RANSAC reprojection threshold, pixels", 0.1, 100.0);
    v("two_way_pnp", two_way_pnp, "refine the PnP on both keyframes' 3D corners, each seen in the other");
    v("guided_radius_px", guided_radius_px,
      "guided matching around the corrected odometry's projection when descriptors find no loop, pixels (0: off)",
      0.0, 1000.0);
    v("use_lines", use_lines, "verify loops that points miss with points and lines together");
    v("line_max_hamming", line_max_hamming, "LBD distance of a line match, bits", 0, 256);
    v("line_max_angle_deg", line_max_angle_deg, "direction difference of a line match, deg", 0.1, 90.0);
    v("max_yaw_change_deg", max_yaw_change_deg, "largest yaw correction of one loop, deg", 0.1, 180.0);
    v("sequential_edges", sequential_edges, "odometry edges from each keyframe to the previous ones", 1, 100);
    v("odometry_sigma_m", odometry_sigma_m, "odometry edge sigma, m", 1e-6, 10.0);
    v("odometry_sigma_per_m", odometry_sigma_per_m, "odometry edge sigma per metre of edge length", 0.0, 1.0);
    v("odometry_sigma_yaw_deg", odometry_sigma_yaw_deg, "odometry edge yaw sigma, deg", 1e-6, 90.0);
    v("loop_sigma_m", loop_sigma_m, "loop edge sigma, m", 1e-6, 10.0);
    v("loop_sigma_yaw_deg", loop_sigma_yaw_deg, "loop edge yaw sigma, deg", 1e-6, 90.0);
    v("loop_pnp_sigma_scale", loop_pnp_sigma_scale, "loop edge sigmas at least this times the PnP's (0: fixed)", 0.0,
      100.0);
    v("full_weight_inliers", full_weight_inliers,
      "loops with fewer PnP inliers n get their edge sigmas multiplied by this / n (0: off)", 0, 100000);
    v("loop_huber", loop_huber, "Huber threshold of a loop edge, sigmas (0: none)", 0.0, 100.0);
    v("max_iterations", max_iterations, "Levenberg-Marquardt iterations per pose-graph solve", 1, 1000);
  }
};

}  // namespace linnet
