#include <cmath>

#include <gtest/gtest.h>

#include "linnet/loop/loop_closer.h"
#include "loop_test_scene.h"

namespace linnet {
namespace {

// Keyframes every 0.5 s along the wall and back (60 s); the body is the camera (T_B_C0 = identity).
struct Flight {
  std::vector<Timestamp> t;
  std::vector<Pose> truth, odometry;
};

Flight fly(double yaw_drift, const Vec3& shift) {
  Flight f;
  for (int k = 0; k <= 120; ++k) {
    const double s = 0.5 * k;
    const double x = s <= 30.0 ? -1.5 + 0.1 * s : 1.5 - 0.1 * (s - 30.0);
    f.t.push_back(static_cast<Timestamp>(s * 1e9));
    f.truth.push_back(test::WallScene::cameraAt(Vec3(x, 0.3 * std::sin(0.2 * s), 1.2 + 0.1 * std::cos(0.3 * s)),
                                                0.1 * std::sin(0.15 * s)));
  }
  f.odometry.push_back(f.truth[0]);
  for (std::size_t k = 1; k < f.truth.size(); ++k) {
    const Pose d = f.truth[k - 1].inverse() * f.truth[k];
    Pose next = f.odometry.back() * Pose(d.q, Vec3(d.p + shift));
    f.odometry.push_back(Pose(Mat3(Eigen::AngleAxisd(yaw_drift, Vec3::UnitZ()).toRotationMatrix() * next.R()),
                              next.p));
  }
  return f;
}

// Flies `f` through the loop closer; returns the RMS position error of the corrected keyframes and, in `last_error`,
// that of the last one.
double closeLoops(const Flight& f, const LoopOptions& o, LoopCloser* loop, double* last_error) {
  const test::WallScene scene;
  for (std::size_t k = 0; k < f.t.size(); ++k) {
    const cv::Mat image = scene.render(f.truth[k]);
    loop->addKeyframe(f.t[k], f.odometry[k], image, scene.trackedCorners(image, f.truth[k], 150));
  }
  EXPECT_GE(loop->loops().size(), 3u);
  for (const LoopEvent& e : loop->loops()) {
    EXPECT_GE(toSeconds(e.t_new - e.t_old), o.min_time_gap_s);
    EXPECT_GE(e.inliers, o.min_inliers);
  }
  double after = 0.0;
  for (std::size_t k = 0; k < f.t.size(); ++k)
    after += ((loop->correctionAt(f.t[k]) * f.odometry[k]).p - f.truth[k].p).squaredNorm();
  *last_error = ((loop->latestCorrection() * f.odometry.back()).p - f.truth.back().p).norm();
  return std::sqrt(after / f.t.size());
}

double rmsDrift(const Flight& f) {
  double before = 0.0;
  for (std::size_t k = 0; k < f.t.size(); ++k) before += (f.odometry[k].p - f.truth[k].p).squaredNorm();
  return std::sqrt(before / f.t.size());
}

// RMS position error of every keyframe with the loop closer's correction of its time.
double correctedRms(const Flight& f, const LoopCloser& loop) {
  double sum = 0.0;
  for (std::size_t k = 0; k < f.t.size(); ++k)
    sum += ((loop.correctionAt(f.t[k]) * f.odometry[k]).p - f.truth[k].p).squaredNorm();
  return std::sqrt(sum / static_cast<double>(f.t.size()));
}

TEST(LoopCloser, ClosesTheLoopsOfAFlightThereAndBackAndRemovesTheDrift) {
  const test::WallScene scene;
  const Flight f = fly(0.0002, Vec3(0.004, 0.002, 0.001));  // 1.4 deg of yaw and 0.5 m over the flight
  LoopOptions o;
  o.enabled = true;
  // Fixed loop sigmas: this flight drifts by 9 % of its path, far beyond the odometry edges' sigmas, so the graph
  // needs stiff loop edges to pull its end back (the PnP-weighted ones are checked below).
  o.loop_pnp_sigma_scale = 0.0;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  double last_error = 0.0;
  const double rms_before = rmsDrift(f), rms_after = closeLoops(f, o, &loop, &last_error);
  EXPECT_GT(rms_before, 0.15);
  EXPECT_LT(rms_after, 0.35 * rms_before) << rms_before << " -> " << rms_after;
  const double last_before = (f.odometry.back().p - f.truth.back().p).norm();
  EXPECT_LT(last_error, 0.3 * last_before) << last_before << " -> " << last_error;
  // correctionAt before the first keyframe, and at a keyframe's own time.
  EXPECT_LT((loop.correctionAt(-1).p).norm(), 1e-12);
  EXPECT_LT((loop.correctionAt(f.t.back()).p - loop.latestCorrection().p).norm(), 1e-12);
}

TEST(LoopCloser, LoopEdgesWeightedByTheirPnPCovarianceStillRemoveTheDrift) {
  const test::WallScene scene;
  const Flight f = fly(0.0002, Vec3(0.004, 0.002, 0.001));
  LoopOptions o;  // loop_pnp_sigma_scale at its default
  o.enabled = true;
  ASSERT_GT(o.loop_pnp_sigma_scale, 0.0);
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  double last_error = 0.0;
  const double rms_before = rmsDrift(f), rms_after = closeLoops(f, o, &loop, &last_error);
  EXPECT_LT(rms_after, 0.35 * rms_before) << rms_before << " -> " << rms_after;
}

TEST(LoopCloser, LoopsOnFewInliersGetLooserEdges) {
  // Fixed sigmas, so that the edge's sigma is the floor times full_weight_inliers / inliers exactly.
  const test::WallScene scene;
  const Flight f = fly(0.0002, Vec3(0.004, 0.002, 0.001));
  for (const int full : {0, 100000}) {
    SCOPED_TRACE(full);
    LoopOptions o;
    o.enabled = true;
    o.loop_pnp_sigma_scale = 0.0;
    o.full_weight_inliers = full;
    LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
    double last_error = 0.0;
    closeLoops(f, o, &loop, &last_error);
    for (const LoopEvent& e : loop.loops()) {
      const double looser = full > 0 ? static_cast<double>(full) / e.inliers : 1.0;
      ASSERT_GT(e.inliers, 0);
      EXPECT_NEAR(e.sigma_m, o.loop_sigma_m * looser, 1e-12 * looser);
      EXPECT_NEAR(e.sigma_yaw_deg, o.loop_sigma_yaw_deg * looser, 1e-9 * looser);
    }
  }
}

TEST(LoopCloser, FindsNoLoopOnAFlightThatNeverComesBack) {
  const test::WallScene scene;
  LoopOptions o;
  o.enabled = true;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  for (int k = 0; k <= 60; ++k) {
    const Pose T = test::WallScene::cameraAt(Vec3(-3.0 + 0.1 * k, 0.0, 1.2), 0.0);
    const cv::Mat image = scene.render(T);
    loop.addKeyframe(static_cast<Timestamp>(k * 5e8), T, image, scene.trackedCorners(image, T, 150));
  }
  EXPECT_TRUE(loop.loops().empty());
  EXPECT_EQ(loop.keyframes(), 61u);
  EXPECT_LT((loop.latestCorrection().p).norm(), 1e-12);
}

TEST(LoopCloser, ARevisitOfADescribedPlaceKeepsNoDescription) {
  // Hovering at two spots in turn, 30 s apart: the first keyframe at each spot describes it, the revisits add
  // graph nodes but no descriptions (they still verify loops against it). Off: every keyframe keeps its own.
  const test::WallScene scene;
  const auto hover = [&](LoopCloser* loop) {
    for (int k = 0; k < 8; ++k) {
      const Pose T = test::WallScene::cameraAt(Vec3(k % 2 == 0 ? -0.5 : 0.5, 0.0, 1.2), 0.0);
      const cv::Mat image = scene.render(T);
      loop->addKeyframe(static_cast<Timestamp>(k * 3e10), T, image, scene.trackedCorners(image, T, 150));
    }
  };
  LoopOptions o;
  o.enabled = true;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  hover(&loop);
  EXPECT_EQ(loop.keyframes(), 8u);
  EXPECT_EQ(loop.describedKeyframes(), 2u);
  EXPECT_FALSE(loop.loops().empty());
  // The revisits that closed no loop are not graph nodes either (o.cull_revisits): the two described keyframes and
  // those of the loops are (the second keyframe may close a loop with the first: their views overlap).
  const LoopStats s = loop.stats();
  EXPECT_GE(s.graph_nodes, 3u);
  EXPECT_LE(s.graph_nodes, 2u + loop.loops().size());
  EXPECT_LT(s.graph_nodes, 8u);
  EXPECT_EQ(s.keyframes, 8u);
  EXPECT_EQ(s.described, 2u);
  o.cull_revisits = false;
  LoopCloser kept(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  hover(&kept);
  EXPECT_EQ(kept.stats().graph_nodes, 8u);
  EXPECT_EQ(kept.loops().size(), loop.loops().size());
  o.place_reuse_m = 0.0;
  LoopCloser all(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  hover(&all);
  EXPECT_EQ(all.describedKeyframes(), 8u);
  // The database's memory follows the described keyframes: four times as many descriptions, about four times the MB.
  EXPECT_GT(s.place_mb, 0.0);
  EXPECT_GT(all.stats().place_mb, 3.0 * s.place_mb);
  EXPECT_LT(all.stats().place_mb, 5.0 * s.place_mb);
}

// A slowly drifting flight through a loop closer with `o` (on, fixed loop sigmas), flushed at the end: the loops,
// the graph solves before and after the flush, and the corrected keyframes' RMS error against the odometry's.
struct Flushed {
  std::size_t loops = 0, solves_before = 0, solves_after = 0;
  double rms = 0.0, drift = 0.0;
};

Flushed flyAndFlush(LoopOptions o) {
  const test::WallScene scene;
  const Flight f = fly(0.0002, Vec3(0.004, 0.002, 0.001));
  o.enabled = true;
  o.loop_pnp_sigma_scale = 0.0;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  double last_error = 0.0;
  closeLoops(f, o, &loop, &last_error);
  Flushed r;
  r.loops = loop.loops().size();
  r.solves_before = loop.stats().graph_solves;
  loop.flush();
  r.solves_after = loop.stats().graph_solves;
  r.rms = correctedRms(f, loop);
  r.drift = rmsDrift(f);
  return r;
}

TEST(LoopCloser, LoopsSolvedInTheNewestNodesStillRemoveTheDriftOnceFlushed) {
  // Every loop solved in the newest 20 graph nodes only (full_solve_sigmas so large that none is "far"), then the
  // whole graph once at the end of the stream: the drift is removed as well as by whole solves.
  LoopOptions o;
  o.consistent_loop_sigmas = 0.0;
  o.solve_window_nodes = 20;
  o.full_solve_sigmas = 1e6;
  const Flushed r = flyAndFlush(o);
  EXPECT_EQ(r.solves_before, r.loops);
  EXPECT_EQ(r.solves_after, r.solves_before + 1);  // the whole graph, once
  EXPECT_LT(r.rms, 0.35 * r.drift) << r.drift << " -> " << r.rms;
}

TEST(LoopCloser, LoopsAddedWithoutASolveAreSolvedWhenFlushed) {
  // Every loop taken as consistent with the graph (consistent_loop_sigmas so large that none is solved when found):
  // their edges wait, and the end of the stream solves them, once.
  LoopOptions o;
  o.consistent_loop_sigmas = 1e6;
  const Flushed r = flyAndFlush(o);
  EXPECT_EQ(r.solves_before, 0u);
  EXPECT_EQ(r.solves_after, 1u);
  EXPECT_LT(r.rms, 0.35 * r.drift) << r.drift << " -> " << r.rms;
}

}  // namespace
}  // namespace linnet
