// LineLandmarks on a small synthetic window with a EuRoC-like stereo rig: triangulation from the stereo pair and
// from two frames, the degenerate and out-of-range cases it must reject, the residuals it hands to the solver,
// the map of lines that left the window, and the outlier / drift checks after a solve.
#include "linnet/estimator/line_landmarks.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "linnet/estimator/factors/line_factor.h"

namespace linnet {
namespace {

constexpr double kFocal = 460.0;
constexpr double kRadToDeg = 180.0 / M_PI;
constexpr Timestamp kT0 = 1'403'715'273'000'000'000;
constexpr Timestamp kDt = 100'000'000;

// cam0 close to the body frame, cam1 0.11 m to its right (along cam0's x), slightly rotated.
const Pose kT_B_C0(expSO3(Vec3(0.01, -0.02, 0.015)), Vec3(-0.02, -0.06, 0.01));
const Pose kT_B_C1 = kT_B_C0 * Pose(expSO3(Vec3(0.002, -0.001, 0.0)), Vec3(0.11, 0.0, 0.0));

// A roughly vertical segment about 3 m ahead of the first frame, and three body poses moving right.
const Vec3 kA(-0.3, -0.8, 3.0), kB(0.2, 0.9, 3.4);
Vec3 along(double s) { return kA + s * (kB - kA); }
std::vector<Pose> bodyPoses() {
  return {Pose(), Pose(expSO3(Vec3(0.0, 0.02, 0.0)), Vec3(0.25, 0.02, 0.05)),
          Pose(expSO3(Vec3(0.01, 0.04, 0.0)), Vec3(0.5, -0.01, 0.1))};
}

Vec2 project(const Pose& T_W_C, const Vec3& p_W) {
  const Vec3 p = T_W_C.inverse() * p_W;
  return p.head<2>() / p.z();
}

/// The segment a-b (W) observed from body pose T_W_B, exact normalised endpoints in cam0 (and cam1).
LineObservation observation(std::int64_t id, const Pose& T_W_B, const Vec3& a, const Vec3& b, bool right) {
  LineObservation o;
  o.id = id;
  o.s0 = project(T_W_B * kT_B_C0, a);
  o.e0 = project(T_W_B * kT_B_C0, b);
  o.has_right = right;
  if (right) {
    o.s1 = project(T_W_B * kT_B_C1, a);
    o.e1 = project(T_W_B * kT_B_C1, b);
  }
  return o;
}

Window makeWindow(int frames) {
  Window w;
  const std::vector<Pose> poses = bodyPoses();
  for (int i = 0; i < frames; ++i) w.push(kT0 + i * kDt).setPose(poses[static_cast<std::size_t>(i)]);
  return w;
}

double angleDeg(const Vec6& L, const Vec3& dir) {
  return std::asin(std::min(1.0, pluckerDirection(L).cross(dir.normalized()).norm())) * kRadToDeg;
}

/// Distance of x to the segment [a, b].
double segmentDistance(const Vec3& a, const Vec3& b, const Vec3& x) {
  const double t = std::clamp((x - a).dot(b - a) / (b - a).squaredNorm(), 0.0, 1.0);
  return (a + t * (b - a) - x).norm();
}

void expectRecovered(const LineLandmark& lm) {
  ASSERT_TRUE(lm.triangulated);
  EXPECT_LT(angleDeg(lm.L(), kB - kA), 0.01);
  EXPECT_LT(pluckerPointDistance(lm.L(), kA), 1e-3);
  EXPECT_LT(pluckerPointDistance(lm.L(), kB), 1e-3);
  EXPECT_NEAR(lm.L().norm(), 1.0, 1e-12);
  ASSERT_TRUE(lm.has_extent);
  EXPECT_LT(segmentDistance(lm.a, lm.b, kA) + segmentDistance(lm.a, lm.b, kB), 1e-6);
  EXPECT_NEAR((lm.b - lm.a).norm(), (kB - kA).norm(), 1e-6);
}

TEST(LineLandmarks, StereoTriangulationInOneFrame) {
  const Window w = makeWindow(1);
  LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
  lines.observe(0, kT0, {observation(7, w[0].T_W_B(), kA, kB, true)});
  EXPECT_EQ(lines.triangulate(w), 1);
  const LineLandmark& lm = lines.all().at(7);
  expectRecovered(lm);
  EXPECT_GT(lm.max_sin_angle, std::sin(1.0 / kRadToDeg));
  EXPECT_EQ(lines.countTriangulatedIn(0), 1);
  EXPECT_EQ(lines.triangulate(w), 0);  // already triangulated

  // Without the right image, one frame has no candidate.
  LineLandmarks mono(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
  mono.observe(0, kT0, {observation(7, w[0].T_W_B(), kA, kB, false)});
  EXPECT_EQ(mono.triangulate(w), 0);
  EXPECT_FALSE(mono.all().at(7).triangulated);
}

TEST(LineLandmarks, TwoFrameTriangulationWithCam0Only) {
  const Window w = makeWindow(2);
  LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, std::nullopt);  // a monocular rig
  // Each frame sees a different part of the segment (the second with its endpoints swapped); the extent is their
  // union.
  lines.observe(0, kT0, {observation(3, w[0].T_W_B(), kA, along(0.6), true)});  // has_right ignored: no cam1
  lines.observe(1, kT0 + kDt, {observation(3, w[1].T_W_B(), kB, along(0.4), false)});
  EXPECT_FALSE(lines.all().at(3).obs.at(0).has_right);
  EXPECT_EQ(lines.triangulate(w), 1);
  expectRecovered(lines.all().at(3));
}

TEST(LineLandmarks, RejectsDegenerateAndOutOfRangeLines) {
  const Window w = makeWindow(3);
  const Pose T_W_C0 = w[0].T_W_B() * kT_B_C0;
  {
    // Parallel to the stereo baseline, one frame: both back-projection planes are the same plane.
    const Vec3 a = T_W_C0 * Vec3(-0.5, 0.3, 3.0), b = a + T_W_C0.q * Vec3(1.0, 0.0, 0.0);
    LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
    lines.observe(0, kT0, {observation(1, w[0].T_W_B(), a, b, true)});
    EXPECT_EQ(lines.triangulate(w), 0);
    EXPECT_FALSE(lines.all().at(1).triangulated);
  }
  {
    // Parallel to the motion of cam0 between two frames, no right image.
    const Vec3 c1 = (w[1].T_W_B() * kT_B_C0).p;
    const Vec3 a = T_W_C0 * Vec3(0.4, -0.3, 3.0), b = a + 1.5 * (c1 - T_W_C0.p).normalized();
    LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
    lines.observe(0, kT0, {observation(2, w[0].T_W_B(), a, b, false)});
    lines.observe(1, kT0 + kDt, {observation(2, w[1].T_W_B(), a, b, false)});
    EXPECT_EQ(lines.triangulate(w), 0);
    EXPECT_FALSE(lines.all().at(2).triangulated);
  }
  {
    // Behind the camera: the stereo planes intersect at a wide angle, but the depths are negative.
    const Vec3 a = T_W_C0 * Vec3(-0.3, -0.8, -3.0), b = T_W_C0 * Vec3(0.2, 0.9, -3.4);
    const LineObservation o = observation(3, w[0].T_W_B(), a, b, true);
    double sin_angle = 0.0;
    intersectPlanes(backProjectionPlane(T_W_C0, o.s0, o.e0),
                    backProjectionPlane(w[0].T_W_B() * kT_B_C1, o.s1, o.e1), &sin_angle);
    EXPECT_GT(sin_angle, std::sin(1.0 / kRadToDeg));
    LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
    lines.observe(0, kT0, {o});
    EXPECT_EQ(lines.triangulate(w), 0);
  }
  {
    // 12 m away, seen from frames 0 and 2 (0.5 m apart): fine with max_depth_m = 30, rejected with 10.
    const Vec3 a = T_W_C0 * Vec3(-0.5, -1.0, 12.0), b = T_W_C0 * Vec3(0.5, 2.0, 12.5);
    for (const double max_depth : {30.0, 10.0}) {
      LineOptions options;
      options.max_depth_m = max_depth;
      LineLandmarks lines(options, kFocal, kT_B_C0, kT_B_C1);
      lines.observe(0, kT0, {observation(4, w[0].T_W_B(), a, b, false)});
      lines.observe(2, kT0 + 2 * kDt, {observation(4, w[2].T_W_B(), a, b, false)});
      EXPECT_EQ(lines.triangulate(w), max_depth > 20.0 ? 1 : 0) << "max_depth_m " << max_depth;
    }
  }
}

/// Frames 0-2 observe line 7 in both images (different parts of the segment); frame 2 also sees line 8 (stereo).
LineLandmarks observedLines(const Window& w, const LineOptions& options = {}) {
  LineLandmarks lines(options, kFocal, kT_B_C0, kT_B_C1);
  lines.observe(0, w[0].t, {observation(7, w[0].T_W_B(), kA, along(0.6), true)});
  lines.observe(1, w[1].t, {observation(7, w[1].T_W_B(), along(0.3), along(0.8), true)});
  lines.observe(2, w[2].t, {observation(7, w[2].T_W_B(), along(0.5), kB, true),
                            observation(8, w[2].T_W_B(), Vec3(1.0, -0.5, 4.0), Vec3(1.2, 0.6, 4.2), true)});
  return lines;
}

TEST(LineLandmarks, ResidualsPerFrameAndCameraWithZeroCostAtTheTruth) {
  Window w = makeWindow(3);
  LineLandmarks lines = observedLines(w);
  EXPECT_EQ(lines.triangulate(w), 2);
  std::vector<ResidualSpec> res = lines.residuals(w);
  ASSERT_EQ(res.size(), 6u);  // line 8 is seen in one frame only: not usable yet
  const double* block = lines.all().at(7).plucker.data();
  EXPECT_TRUE(lines.all().at(7).used && lines.all().at(7).solved);
  EXPECT_FALSE(lines.all().at(8).used);
  EXPECT_EQ(lines.countUsed(), 1);
  // Set the block to the true line: every residual vanishes.
  Eigen::Map<Vec6> L(res[0].blocks[1]);
  L = normalisePlucker(pluckerFromPoints(kA, kB));
  for (std::size_t k = 0; k < res.size(); ++k) {
    const ResidualSpec& r = res[k];
    const FrameId frame = static_cast<FrameId>(k / 2);  // cam0, then cam1, per frame
    EXPECT_EQ(r.keys.vector(), (std::vector<std::int64_t>{frameBlockKey(frame, BlockKind::kPose), lineBlockKey(7)}));
    EXPECT_EQ(r.blocks.vector(), (std::vector<double*>{w.find(frame)->pose.data(), const_cast<double*>(block)}));
    EXPECT_TRUE(r.line);
    EXPECT_TRUE(r.robust);
    ASSERT_EQ(r.cost->num_residuals(), 2);
    Vec2 e;
    ASSERT_TRUE(r.cost->Evaluate(r.blocks.data(), e.data(), nullptr));
    EXPECT_LT(e.norm(), 1e-8) << k;
  }
  // Moved off the truth: a frame weight of 4 doubles that frame's residuals.
  L = normalisePlucker(transformPlucker(Pose(Quat::Identity(), Vec3(0.02, 0.0, 0.0)), L));
  const std::vector<ResidualSpec> weighted = lines.residuals(w, -1, {{1, 4.0}});
  ASSERT_EQ(weighted.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    Vec2 e0, e1;
    ASSERT_TRUE(res[k].cost->Evaluate(res[k].blocks.data(), e0.data(), nullptr));
    ASSERT_TRUE(weighted[k].cost->Evaluate(weighted[k].blocks.data(), e1.data(), nullptr));
    EXPECT_GT(e0.norm(), 0.5);
    EXPECT_LT((e1 - (k / 2 == 1 ? 2.0 : 1.0) * e0).norm(), 1e-9 * e0.norm()) << k;
  }
  // Marginalisation selection by host frame (the oldest observation), without touching `used`.
  EXPECT_EQ(lines.residuals(w, 0).size(), 6u);
  EXPECT_EQ(lines.residuals(w, 1).size(), 0u);
  EXPECT_EQ(lines.countUsed(), 1);
  // cam0 only when the right residuals are off.
  LineOptions no_right;
  no_right.right_residuals = false;
  LineLandmarks left = observedLines(w, no_right);
  left.triangulate(w);
  EXPECT_EQ(left.residuals(w).size(), 3u);
}

TEST(LineLandmarks, SolvedLinesStayInTheMapAfterLeavingTheWindow) {
  Window w = makeWindow(3);
  LineLandmarks lines = observedLines(w);
  ASSERT_EQ(lines.triangulate(w), 2);
  EXPECT_EQ(lines.mapLines().size(), 2u);  // the window's triangulated lines with an extent
  lines.residuals(w);                      // line 7 takes part in a solve, line 8 does not
  lines.removeFrame(w, 0);
  lines.removeFrame(w, 1);
  EXPECT_EQ(lines.all().count(7), 1u);
  EXPECT_TRUE(lines.residuals(w).empty());  // one observation left: not in the last solve any more
  EXPECT_FALSE(lines.all().at(7).used);
  lines.removeFrame(w, 2);
  EXPECT_TRUE(lines.all().empty());
  const std::vector<MapLine> map = lines.mapLines();
  ASSERT_EQ(map.size(), 1u);
  const MapLine& m = map[0];
  EXPECT_EQ(m.id, 7);
  EXPECT_EQ(m.observations, 3);
  EXPECT_EQ(m.t_last, w[2].t);
  EXPECT_GT(m.angle_deg, 1.0);
  // The extent covers every observed part, i.e. the whole segment, and nothing more.
  EXPECT_LT(segmentDistance(m.a, m.b, kA) + segmentDistance(m.a, m.b, kB), 1e-6);
  EXPECT_NEAR((m.b - m.a).norm(), (kB - kA).norm(), 1e-6);
  // clear() (a new window) keeps the solved lines too.
  LineLandmarks again = observedLines(w);
  again.triangulate(w);
  again.residuals(w);
  again.clear();
  EXPECT_TRUE(again.all().empty());
  ASSERT_EQ(again.mapLines().size(), 1u);
  EXPECT_EQ(again.mapLines()[0].id, 7);
}

TEST(LineLandmarks, ALineLeavingTheWindowIsRefinedOnAllItsObservations) {
  // The window's estimate is off by 5 cm (as a line whose early views were marginalised may be); its sightings at
  // the frames' poses put it back on the true segment when it leaves for the map. With map_refine off the map keeps
  // the window's segment.
  for (const bool refine : {true, false}) {
    Window w = makeWindow(3);
    LineOptions o;
    o.map_refine = refine;
    LineLandmarks lines = observedLines(w, o);
    ASSERT_EQ(lines.triangulate(w), 2);
    const std::vector<ResidualSpec> res = lines.residuals(w);
    ASSERT_FALSE(res.empty());
    Eigen::Map<Vec6> L(res[0].blocks[1]);
    L = normalisePlucker(transformPlucker(Pose(Quat::Identity(), Vec3(0.05, 0.0, 0.0)), Vec6(L)));
    const Vec3 window_a = lines.all().at(7).a, window_b = lines.all().at(7).b;
    for (FrameId f = 0; f < 3; ++f) lines.removeFrame(w, f);
    const std::vector<MapLine> map = lines.mapLines();
    ASSERT_EQ(map.size(), 1u);
    if (refine) {
      EXPECT_LT(segmentDistance(map[0].a, map[0].b, kA) + segmentDistance(map[0].a, map[0].b, kB), 1e-4);
      EXPECT_NEAR((map[0].b - map[0].a).norm(), (kB - kA).norm(), 1e-4);
    } else {
      // The window's estimate, as the map keeps it (single precision).
      for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(map[0].a[i], static_cast<double>(static_cast<float>(window_a[i]))) << i;
        EXPECT_EQ(map[0].b[i], static_cast<double>(static_cast<float>(window_b[i]))) << i;
      }
    }
  }
}

TEST(LineLandmarks, ALineStillInTheWindowIsRefinedForTheMapToo) {
  // At the end of a run some lines are still in the window. Given the window, mapLines() refines them like the lines
  // that left it. The line is triangulated while the window's poses are 5 cm off (its estimate and extent are off
  // too); at the poses put right, one frame leaves (its sightings kept) and two stay in.
  Window w = makeWindow(3);
  LineLandmarks lines = observedLines(w);
  const Pose shift(Quat::Identity(), Vec3(0.05, 0.0, 0.0));
  for (int k = 0; k < 3; ++k) w[k].setPose(shift * w[k].T_W_B());
  ASSERT_EQ(lines.triangulate(w), 2);
  for (int k = 0; k < 3; ++k) w[k].setPose(shift.inverse() * w[k].T_W_B());
  lines.removeFrame(w, 0);
  ASSERT_EQ(lines.all().count(7), 1u);
  const auto find7 = [](const std::vector<MapLine>& map) {
    return *std::find_if(map.begin(), map.end(), [](const MapLine& m) { return m.id == 7; });
  };
  const MapLine plain = find7(lines.mapLines());  // without the window: its estimate, 5 cm off
  EXPECT_GT(segmentDistance(plain.a, plain.b, kA), 0.04);
  const MapLine refined = find7(lines.mapLines(&w));
  EXPECT_LT(segmentDistance(refined.a, refined.b, kA) + segmentDistance(refined.a, refined.b, kB), 1e-4);
  EXPECT_NEAR((refined.b - refined.a).norm(), (kB - kA).norm(), 1e-4);
  EXPECT_EQ(refined.observations, plain.observations);
  EXPECT_EQ(refined.t_last, plain.t_last);
}

TEST(LineLandmarks, SightingsKeptForTheMapStayBounded) {
  // A camera at rest drops a frame per image while a line stays tracked: its sightings must not grow without bound.
  Window w;
  LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
  for (FrameId i = 0; i < 600; ++i) {
    w.push(kT0 + i * kDt).setPose(Pose());
    lines.observe(i, w.newest().t, {observation(7, Pose(), kA, kB, true)});
    if (i > 0) lines.removeFrame(w, i - 1);
  }
  const std::size_t kept = lines.all().at(7).left_window.size();
  EXPECT_GE(kept, 100u);
  EXPECT_LE(kept, 200u);
}

TEST(LineLandmarks, RejectOutliersRemovesAShiftedLineAndTracksTheExtent) {
  Window w = makeWindow(3);
  {
    LineLandmarks lines = observedLines(w);
    lines.triangulate(w);
    const std::vector<ResidualSpec> res = lines.residuals(w);
    EXPECT_EQ(lines.rejectOutliers(w), 0);  // the line fits
    ASSERT_EQ(lines.all().count(7), 1u);
    // Shift the Plücker block 0.5 m sideways (as a diverged solve could): mean error ~75 px.
    Eigen::Map<Vec6> L(res[0].blocks[1]);
    L = normalisePlucker(transformPlucker(Pose(Quat::Identity(), Vec3(0.5, 0.0, 0.0)), Vec6(L)));
    EXPECT_EQ(lines.rejectOutliers(w), 1);
    EXPECT_EQ(lines.lastRejections().reprojection, 1);
    EXPECT_EQ(lines.all().count(7), 0u);
    EXPECT_EQ(lines.all().count(8), 1u);  // not used in the solve: not checked
  }
  for (const double far : {1.3, 2.5}) {
    // Triangulated from frames 0-1; the newest frame then sees a part of the same line beyond the extent [0, 1]:
    // touching it (0.9..1.3) extends it, 1.4 segment lengths away (2.4..2.5) is a drifted track.
    LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
    lines.observe(0, w[0].t, {observation(7, w[0].T_W_B(), kA, along(0.6), true)});
    lines.observe(1, w[1].t, {observation(7, w[1].T_W_B(), along(0.3), kB, true)});
    ASSERT_EQ(lines.triangulate(w), 1);
    const double start = far < 2.0 ? 0.9 : 2.4;
    lines.observe(2, w[2].t, {observation(7, w[2].T_W_B(), along(start), along(far), true)});
    lines.residuals(w);
    if (far < 2.0) {
      EXPECT_EQ(lines.rejectOutliers(w), 0);
      const LineLandmark& lm = lines.all().at(7);
      EXPECT_LT(segmentDistance(lm.a, lm.b, kA) + segmentDistance(lm.a, lm.b, along(far)), 1e-6);
      EXPECT_NEAR((lm.b - lm.a).norm(), far * (kB - kA).norm(), 1e-6);
    } else {
      EXPECT_EQ(lines.rejectOutliers(w), 1);
      EXPECT_EQ(lines.lastRejections().drifted, 1);
    }
  }
}

/// The observation of `a`-`b` from T_W_B with its cam0 (or cam1) segment moved `px` pixels across the line.
LineObservation shifted(std::int64_t id, const Pose& T_W_B, const Vec3& a, const Vec3& b, double px, bool cam1) {
  LineObservation o = observation(id, T_W_B, a, b, true);
  Vec2& s = cam1 ? o.s1 : o.s0;
  Vec2& e = cam1 ? o.e1 : o.e0;
  const Vec2 d = (e - s).normalized();
  const Vec2 normal(-d.y(), d.x());
  s += px / kFocal * normal;
  e += px / kFocal * normal;
  return o;
}

/// Line 7 seen exactly in frames 0 and 2 and as `middle` in frame 1, triangulated and set to the true line.
LineLandmarks withMiddleSighting(const Window& w, const LineObservation& middle) {
  LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
  lines.observe(0, w[0].t, {observation(7, w[0].T_W_B(), kA, along(0.6), true)});
  lines.observe(1, w[1].t, {middle});
  lines.observe(2, w[2].t, {observation(7, w[2].T_W_B(), along(0.5), kB, true)});
  EXPECT_EQ(lines.triangulate(w), 1);
  Eigen::Map<Vec6>(lines.residuals(w)[0].blocks[1]) = normalisePlucker(pluckerFromPoints(kA, kB));
  return lines;
}

TEST(LineLandmarks, OneBadSightingIsDroppedAndTheLineKept) {
  Window w = makeWindow(3);
  for (const bool cam1 : {false, true}) {
    // Frame 1's segment (cam0, or only cam1) lies 12 px off a line that the other sightings fit exactly: the mean
    // error (2 px over six sightings) keeps the line, the sighting goes.
    LineLandmarks lines = withMiddleSighting(w, shifted(7, w[1].T_W_B(), along(0.3), along(0.8), 12.0, cam1));
    EXPECT_EQ(lines.rejectOutliers(w), 0);
    EXPECT_EQ(lines.lastRejections().sightings, 1);
    const LineLandmark& lm = lines.all().at(7);
    EXPECT_EQ(lm.obs.size(), cam1 ? 3u : 2u) << cam1;
    if (cam1) {
      EXPECT_FALSE(lm.obs.at(1).has_right);
    }
    EXPECT_EQ(lines.residuals(w).size(), cam1 ? 5u : 4u);  // cam1 alone, or the frame's cam0 and cam1
  }
  // Within max_observation_px (4 px): kept.
  LineLandmarks lines = withMiddleSighting(w, shifted(7, w[1].T_W_B(), along(0.3), along(0.8), 4.0, false));
  EXPECT_EQ(lines.rejectOutliers(w), 0);
  EXPECT_EQ(lines.lastRejections().sightings, 0);
  EXPECT_EQ(lines.all().at(7).obs.size(), 3u);
}

TEST(LineLandmarks, TheNewestFramesBadSightingIsGatedBeforeTheSolve) {
  Window w = makeWindow(3);
  for (const double px : {0.5, 8.0}) {
    LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
    lines.observe(0, w[0].t, {observation(7, w[0].T_W_B(), kA, along(0.6), true)});
    lines.observe(1, w[1].t, {observation(7, w[1].T_W_B(), along(0.3), kB, true)});
    ASSERT_EQ(lines.triangulate(w), 1);
    lines.observe(2, w[2].t, {shifted(7, w[2].T_W_B(), along(0.5), kB, px, false)});
    EXPECT_EQ(lines.gateNewest(w), 0);  // never solved yet: no judgement
    lines.residuals(w);                 // now it has been
    EXPECT_EQ(lines.gateNewest(w), px > 5.0 ? 1 : 0) << px;
    EXPECT_EQ(lines.all().at(7).obs.count(2), px > 5.0 ? 0u : 1u) << px;
    EXPECT_EQ(lines.all().at(7).obs.count(1), 1u);
  }
}

// A line the front-end lost and found again under a new id: its first sighting lies on the projection of a solved
// window line, which it joins (the new id then names that line); also when a second estimate of the same line lies
// beside it (a duplicate, within reid_px of the first); not when the polarity is reversed (the other side of a bar),
// when a second line lies on the other side of the sighting (a parallel edge), or when it lies elsewhere.
TEST(LineLandmarks, ANewTrackOnAWindowLinesProjectionContinuesThatLine) {
  const Window w = makeWindow(3);
  const Vec3 px(0.0065, 0.0, 0.0);  // about 1 px beside the line at 3 m
  enum Variant { kJoins, kReversed, kParallel, kElsewhere, kDuplicate };
  for (const Variant variant : {kJoins, kReversed, kParallel, kElsewhere, kDuplicate}) {
    SCOPED_TRACE(variant);
    LineLandmarks lines(LineOptions{}, kFocal, kT_B_C0, kT_B_C1);
    const Vec3 second = variant == kParallel ? -3.0 * px : 0.6 * px;
    for (int i = 0; i < 2; ++i) {
      std::vector<LineObservation> seen = {observation(7, w[i].T_W_B(), kA, kB, true)};
      if (variant == kParallel || variant == kDuplicate)
        seen.push_back(observation(8, w[i].T_W_B(), kA + second, kB + second, true));
      lines.observe(i, w[i].t, seen);
    }
    ASSERT_EQ(lines.triangulate(w), variant == kParallel || variant == kDuplicate ? 2 : 1);
    lines.residuals(w);  // solved
    LineObservation again = observation(20, w[2].T_W_B(), along(0.2), along(0.9), true);
    if (variant == kReversed) again = observation(20, w[2].T_W_B(), along(0.9), along(0.2), true);
    if (variant == kElsewhere) again = observation(20, w[2].T_W_B(), along(0.2) + 4.0 * px, along(0.9) + 4.0 * px, true);
    lines.observe(2, w[2].t, {again});
    const bool joins = variant == kJoins || variant == kDuplicate;
    EXPECT_EQ(lines.reidentify(w), joins ? 1 : 0);
    EXPECT_EQ(lines.all().count(20), joins ? 0u : 1u);
    EXPECT_EQ(lines.all().at(7).obs.count(2), joins ? 1u : 0u);
    if (variant != kJoins) continue;
    EXPECT_EQ(lines.all().at(7).observations, 3);
    // The new id names line 7 for the loop closer, and its later sightings go to line 7.
    const std::vector<MapLine> named = lines.windowLines();
    ASSERT_EQ(named.size(), 2u);
    EXPECT_EQ(named[0].id, 7);
    EXPECT_EQ(named[1].id, 20);
    EXPECT_EQ(named[1].a, named[0].a);
    Window later = makeWindow(3);
    lines.removeFrame(later, 0);
    lines.observe(0, w[0].t, {observation(20, w[0].T_W_B(), kA, kB, false)});  // frame id reused as a later frame
    EXPECT_EQ(lines.all().count(20), 0u);
    EXPECT_EQ(lines.all().at(7).obs.count(0), 1u);
  }
}

// With reid_map, a line that left the window for the map is found again by a new track and comes back into the
// window with its sightings: it leaves the map, and goes back into it once, with every sighting, under its own id.
TEST(LineLandmarks, AMapLineFoundAgainComesBackIntoTheWindow) {
  Window w = makeWindow(3);
  for (const bool reid_map : {false, true}) {
    SCOPED_TRACE(reid_map);
    LineOptions options;
    options.reid_map = reid_map;
    LineLandmarks lines(options, kFocal, kT_B_C0, kT_B_C1);
    for (int i = 0; i < 2; ++i) lines.observe(i, w[i].t, {observation(7, w[i].T_W_B(), kA, kB, true)});
    ASSERT_EQ(lines.triangulate(w), 1);
    lines.residuals(w);
    lines.removeFrame(w, 0);
    lines.removeFrame(w, 1);
    ASSERT_TRUE(lines.all().empty());
    ASSERT_EQ(lines.mapLines().size(), 1u);
    lines.observe(2, w[2].t, {observation(30, w[2].T_W_B(), along(0.1), along(0.8), true)});
    EXPECT_EQ(lines.reidentify(w), reid_map ? 1 : 0);
    if (!reid_map) continue;
    ASSERT_EQ(lines.all().count(7), 1u);
    const LineLandmark& back = lines.all().at(7);
    EXPECT_EQ(back.observations, 3);
    EXPECT_EQ(back.left_window.size(), 4u);  // two frames' cam0 and cam1 sightings
    EXPECT_TRUE(back.triangulated && back.solved);
    EXPECT_EQ(lines.mapLines().size(), 1u);  // the window's line 7 only: it left the map
    lines.removeFrame(w, 2);
    const std::vector<MapLine> map = lines.mapLines();
    ASSERT_EQ(map.size(), 1u);
    EXPECT_EQ(map[0].id, 7);
    EXPECT_EQ(map[0].observations, 3);
    EXPECT_EQ(map[0].t_last, w[2].t);
  }
}

}  // namespace
}  // namespace linnet
