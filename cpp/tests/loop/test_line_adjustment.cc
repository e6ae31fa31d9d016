// The global adjustment of the line map (LoopCloser::adjustLines): a flight along a wall and back, with a drifting
// odometry and no place-recognition loop, and the wall's lines mapped once per pass. The adjustment joins each line's
// two passes, solves the keyframes' corrections with them, and re-estimates the lines at the corrected poses. (The
// keyframes' absolute error is not a test here: all the lines lie in one wall, a weak geometry for the poses.)
#include <cmath>
#include <map>
#include <vector>

#include <gtest/gtest.h>

#include "linnet/geometry/plucker.h"
#include "linnet/loop/loop_closer.h"
#include "loop_test_scene.h"

namespace linnet {
namespace {

struct WallFlight {
  std::vector<Timestamp> t;
  std::vector<Pose> truth, odometry;
};

// Keyframes every 0.5 s along the wall (y = 5) from x = -1.5 to 1.5 and back, the camera 3-4 m from it; the odometry
// drifts in yaw and position.
WallFlight wallFlight() {
  WallFlight f;
  for (int k = 0; k <= 60; ++k) {
    const double s = 0.5 * k;
    const double x = s <= 15.0 ? -1.5 + 0.2 * s : 1.5 - 0.2 * (s - 15.0);
    f.t.push_back(static_cast<Timestamp>((1.0 + s) * 1e9));
    f.truth.push_back(test::WallScene::cameraAt(Vec3(x, 1.2 + 0.3 * std::sin(0.4 * s), 1.2), 0.1 * std::sin(0.3 * s)));
  }
  f.odometry.push_back(f.truth[0]);
  for (std::size_t k = 1; k < f.truth.size(); ++k) {
    const Pose d = f.truth[k - 1].inverse() * f.truth[k];
    Pose next = f.odometry.back() * Pose(d.q, Vec3(d.p + Vec3(0.0004, 0.0, 0.0002)));
    f.odometry.push_back(
        Pose(Mat3(Eigen::AngleAxisd(0.0002, Vec3::UnitZ()).toRotationMatrix() * next.R()), next.p));
  }
  return f;
}

Vec2 project(const Pose& T_W_C, const Vec3& p) {
  const Vec3 q = T_W_C.inverse() * p;
  return q.head<2>() / q.z();
}

struct Mapped {
  std::vector<std::pair<Vec3, Vec3>> truth;  // the wall's lines
  std::vector<MapLine> lines;                // each line once per pass, in the odometry's world
  std::map<std::int64_t, std::vector<LineSighting>> sightings;
};

// Each pass's map line: refined on that pass's sightings (cam0 and cam1) at the odometry's poses, as the estimator
// archives it.
Mapped mapWall(const WallFlight& f, const Pose& T_C1_C0) {
  Mapped m;
  for (double x : {-1.0, -0.4, 0.3, 0.9}) m.truth.push_back({Vec3(x, 5.0, 0.4), Vec3(x, 5.0, 2.0)});
  for (double z : {0.6, 1.4, 2.1}) m.truth.push_back({Vec3(-1.2, 5.0, z), Vec3(1.1, 5.0, z + 0.05)});
  const Pose T_C0_C1 = T_C1_C0.inverse();
  std::int64_t id = 0;
  for (int pass = 0; pass < 2; ++pass) {
    for (const auto& [a, b] : m.truth) {
      std::vector<LineSighting> s;
      for (std::size_t k = pass == 0 ? 0 : 31; k <= (pass == 0 ? 30u : 60u); ++k)
        for (const Pose& T_C0_Ci : {Pose::identity(), T_C0_C1}) {
          const Pose cam = f.truth[k] * T_C0_Ci;
          s.push_back({f.odometry[k] * T_C0_Ci, project(cam, a + 0.1 * (b - a)), project(cam, a + 0.9 * (b - a)),
                       f.t[k]});
        }
      Vec6 L = normalisePlucker(pluckerFromPoints(a, b));
      LineRefinementOptions ro;
      ro.focal_px = 458.0;
      refineLine(s, ro, &L);
      MapLine l;
      l.id = id++;
      l.a = L.tail<3>().cross(L.head<3>()) / L.tail<3>().squaredNorm();  // closest point to the origin ...
      l.b = l.a + L.tail<3>().normalized();                               // ... and 1 m along the line
      l.observations = static_cast<int>(s.size() / 2);
      l.t_last = s.back().t;
      l.sigma_m = lineEndpointSigmaM(L, s, l.a, l.b, 458.0, 1.5);
      m.lines.push_back(l);
      m.sightings[l.id] = s;
    }
  }
  return m;
}

double worstOffset(const MapLine& l, const std::pair<Vec3, Vec3>& truth) {
  const Vec6 L = normalisePlucker(pluckerFromPoints(truth.first, truth.second));
  return std::max(pluckerPointDistance(L, l.a), pluckerPointDistance(L, l.b));
}

TEST(LineAdjustment, JoinsThePassesOfALineAndMakesThemAgree) {
  const test::WallScene scene;
  const WallFlight f = wallFlight();
  LoopOptions o;
  o.cull_revisits = false;  // every keyframe a node (a culled revisit's frames would share one correction)
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  const cv::Mat blank(480, 752, CV_8U, cv::Scalar(0));
  for (std::size_t k = 0; k < f.t.size(); ++k) loop.addKeyframe(f.t[k], f.odometry[k], blank, {});
  loop.flush();
  ASSERT_TRUE(loop.loops().empty());  // no place recognition on blank images: only the lines can help
  Mapped m = mapWall(f, scene.T_C1_C0);
  const std::size_t n = m.truth.size();
  MapLine unseen;  // a line without sightings is only corrected
  unseen.id = 100;
  unseen.a = Vec3(0.0, 4.0, 0.0);
  unseen.b = Vec3(1.0, 4.0, 0.0);
  unseen.t_last = f.t[20];
  m.lines.push_back(unseen);
  double pass2_before = 0.0;
  for (std::size_t i = 0; i < n; ++i) pass2_before = std::max(pass2_before, worstOffset(m.lines[n + i], m.truth[i]));
  ASSERT_GT(pass2_before, 0.005);

  LineAdjustmentOptions ao;
  ao.focal_px = 458.0;
  LineAdjustmentStats st;
  const std::vector<MapLine> out = loop.adjustLines(m.lines, m.sightings, ao, &st);
  EXPECT_EQ(st.lines, 2 * n + 1);
  EXPECT_EQ(st.joined, 2 * n);
  EXPECT_EQ(st.groups, n);
  EXPECT_TRUE(st.solved);
  // Every map line is published, by id, each re-estimated at the corrected poses: the return pass's lines come nearer
  // the truth, and the two passes' lines of one physical line nearer each other.
  ASSERT_EQ(out.size(), 2 * n + 1);
  for (std::size_t i = 0; i + 1 < out.size(); ++i) EXPECT_LT(out[i].id, out[i + 1].id);
  double pass2_after = 0.0, disagreement_before = 0.0, disagreement_after = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    pass2_after = std::max(pass2_after, worstOffset(out[n + i], m.truth[i]));
    disagreement_before = std::max(disagreement_before, worstOffset(m.lines[n + i], {m.lines[i].a, m.lines[i].b}));
    disagreement_after = std::max(disagreement_after, worstOffset(out[n + i], {out[i].a, out[i].b}));
  }
  EXPECT_LT(pass2_after, 0.5 * pass2_before);
  // They come closer (0.045 -> 0.034 m), not together: see docs/known_issues.md (stop 53, the global adjustment).
  EXPECT_LT(disagreement_after, 0.85 * disagreement_before);
  // The line without sightings moved with the final correction of its last sighting's keyframe.
  EXPECT_LT((out.back().a - loop.correctionAt(unseen.t_last) * unseen.a).norm(), 1e-12);

  // Published joined: one line per physical line, with both passes' observations.
  LoopCloser again(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  for (std::size_t k = 0; k < f.t.size(); ++k) again.addKeyframe(f.t[k], f.odometry[k], blank, {});
  again.flush();
  ao.publish_joined = true;
  m.lines.pop_back();
  const std::vector<MapLine> joined = again.adjustLines(m.lines, m.sightings, ao, &st);
  ASSERT_EQ(joined.size(), n);
  for (const MapLine& l : joined) EXPECT_EQ(l.observations, m.lines[0].observations + m.lines[n].observations);
}

TEST(LineAdjustment, ParallelEdgesApartAreNotJoined) {
  const test::WallScene scene;
  const WallFlight f = wallFlight();
  LoopOptions o;
  o.cull_revisits = false;
  LoopCloser loop(o, *scene.camera, Pose::identity(), scene.T_C1_C0);
  const cv::Mat blank(480, 752, CV_8U, cv::Scalar(0));
  for (std::size_t k = 0; k < f.t.size(); ++k) loop.addKeyframe(f.t[k], f.odometry[k], blank, {});
  loop.flush();
  Mapped m = mapWall(f, scene.T_C1_C0);
  // The return pass sees lines 8 cm beside the outward pass's (a door frame's two edges): no join, no solve.
  const std::size_t n = m.truth.size();
  for (std::size_t i = 0; i < n; ++i) {
    MapLine& l = m.lines[n + i];
    std::vector<LineSighting>& s = m.sightings[l.id];
    const Vec3 shift = (m.truth[i].second - m.truth[i].first).cross(Vec3::UnitY()).normalized() * 0.08;
    const auto& [a, b] = m.truth[i];
    for (std::size_t q = 0; q < s.size(); ++q) {
      const std::size_t k = 31 + q / 2;
      const Pose cam = f.truth[k] * (q % 2 == 0 ? Pose::identity() : scene.T_C1_C0.inverse());
      s[q].s = project(cam, a + shift + 0.1 * (b - a));
      s[q].e = project(cam, a + shift + 0.9 * (b - a));
    }
    l.a += shift;
    l.b += shift;
  }
  LineAdjustmentStats st;
  LineAdjustmentOptions ao;
  ao.focal_px = 458.0;
  loop.adjustLines(m.lines, m.sightings, ao, &st);
  EXPECT_EQ(st.joined, 0u);
  EXPECT_EQ(st.groups, 0u);
}

}  // namespace
}  // namespace linnet
