#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "linnet/loop/pose_graph.h"

#include "linnet/geometry/plucker.h"

namespace linnet {
namespace {

// A pose with the given yaw and a fixed small tilt (roll and pitch), at p.
Pose tilted(double yaw, const Vec3& p) {
  const Mat3 tilt = (expSO3(Vec3(0.05, -0.03, 0.0))).toRotationMatrix();
  return Pose(Mat3(rotZ(yaw) * tilt), p);
}

// Keyframes around a circle of radius 3 m, back to the start: truth, and odometry that drifts in yaw and position.
struct Circle {
  std::vector<Pose> truth, odometry;
};

Circle makeCircle(int n, double yaw_drift_per_step, const Vec3& shift_per_step) {
  Circle c;
  for (int k = 0; k <= n; ++k) {
    const double a = 2.0 * M_PI * k / n;
    c.truth.push_back(tilted(a + M_PI / 2, Vec3(3.0 * std::cos(a), 3.0 * std::sin(a), 1.0)));
  }
  // Odometry: the true increments, each perturbed by a yaw error and a shift (in the previous frame).
  c.odometry.push_back(c.truth[0]);
  for (int k = 1; k <= n; ++k) {
    Pose d = c.truth[static_cast<std::size_t>(k - 1)].inverse() * c.truth[static_cast<std::size_t>(k)];
    d = Pose(Mat3(d.R()), Vec3(d.p + shift_per_step));
    Pose next = c.odometry.back() * d;
    next = Pose(Mat3(rotZ(yaw_drift_per_step) * next.R()), next.p);
    c.odometry.push_back(next);
  }
  return c;
}

double yawError(const Pose& a, const Pose& b) {
  return std::abs(std::remainder(yawOf(a.R(), 0) - yawOf(b.R(), 0), 2.0 * M_PI));
}

TEST(PoseGraph, YawAndRotZAreInverse) {
  for (double yaw : {-3.0, -1.0, 0.0, 0.5, 3.1}) EXPECT_NEAR(yawOf(rotZ(yaw), 0), yaw, 1e-12);
  // A rotation about z adds to the heading of a tilted attitude, for any non-vertical axis.
  const Mat3 R = tilted(0.2, Vec3::Zero()).R();
  for (int axis : {0, 1}) EXPECT_NEAR(yawOf(rotZ(0.5) * R, axis), yawOf(R, axis) + 0.5, 1e-12);
  EXPECT_EQ(horizontalAxis(R), 0);
}

TEST(PoseGraph, ABodyWithItsXAxisUpGetsAWellDefinedHeading) {
  // The EuRoC MAV's IMU: x up, z forward. Its z-y-x yaw is degenerate; the graph uses the most horizontal axis.
  Mat3 R_up;
  R_up.col(0) = Vec3(0.02, 0.0, 1.0).normalized();
  R_up.col(2) = Vec3(1.0, 0.0, -0.02).normalized();
  R_up.col(1) = R_up.col(2).cross(R_up.col(0));
  EXPECT_NE(horizontalAxis(R_up), 0);
  PoseGraph g;
  g.addNode(Pose(R_up, Vec3::Zero()));
  g.addNode(Pose(Mat3(rotZ(0.3) * R_up), Vec3(1.0, 0.0, 0.0)));
  const PoseGraphEdge e = g.odometryEdge(0, 1, 0.01, 1e-3);
  EXPECT_NEAR(e.yaw_ij, 0.3, 1e-12);
  const PoseGraphEdge l = g.loopEdge(0, 1, g.odometryPose(0).inverse() * g.odometryPose(1), 0.01, 1e-3);
  EXPECT_NEAR(l.yaw_ij, 0.3, 1e-12);
  EXPECT_LT((l.t_ij - e.t_ij).norm(), 1e-12);
}

TEST(PoseGraph, OdometryAloneKeepsTheOdometry) {
  const Circle c = makeCircle(40, 0.002, Vec3(0.01, 0.0, 0.0));
  PoseGraph g;
  for (const Pose& p : c.odometry) g.addNode(p);
  for (std::size_t k = 1; k < c.odometry.size(); ++k)
    for (std::size_t i = (k >= 3 ? k - 3 : 0); i < k; ++i) g.addEdge(g.odometryEdge(i, k, 0.01, 1e-3));
  ASSERT_TRUE(g.optimise(PoseGraphOptions{}));
  for (std::size_t k = 0; k < c.odometry.size(); ++k) {
    EXPECT_LT((g.pose(k).p - c.odometry[k].p).norm(), 1e-9);
    EXPECT_LT((g.pose(k).R() - c.odometry[k].R()).norm(), 1e-9);
    EXPECT_LT((g.correction(k).p).norm() + (g.correction(k).R() - Mat3::Identity()).norm(), 1e-9);
  }
}

TEST(PoseGraph, ALoopEdgeRemovesTheDriftAndKeepsRollAndPitch) {
  const int n = 60;
  const Circle c = makeCircle(n, 0.003, Vec3(0.004, -0.002, 0.001));
  PoseGraph g;
  for (const Pose& p : c.odometry) g.addNode(p);
  for (std::size_t k = 1; k < c.odometry.size(); ++k)
    for (std::size_t i = (k >= 4 ? k - 4 : 0); i < k; ++i) g.addEdge(g.odometryEdge(i, k, 0.01, 1e-3));
  const std::size_t last = static_cast<std::size_t>(n);
  const double drift_before = (c.odometry[last].p - c.truth[last].p).norm();
  const double yaw_before = yawError(c.odometry[last], c.truth[last]);
  ASSERT_GT(drift_before, 0.2);
  ASSERT_GT(yaw_before, 0.1);
  // The loop: the last keyframe measured against the first, with the true relative pose.
  g.addEdge(g.loopEdge(0, last, c.truth[0].inverse() * c.truth[last], 1e-3, 1e-4));
  ASSERT_TRUE(g.optimise(PoseGraphOptions{}));
  EXPECT_LT((g.pose(last).p - c.truth[last].p).norm(), 0.05 * drift_before);
  EXPECT_LT(yawError(g.pose(last), c.truth[last]), 0.05 * yaw_before);
  // Halfway, the error is also reduced (the correction is spread along the loop).
  const std::size_t mid = last / 2;
  EXPECT_LT((g.pose(mid).p - c.truth[mid].p).norm(), (c.odometry[mid].p - c.truth[mid].p).norm());
  for (std::size_t k = 0; k <= last; ++k) {
    // Roll and pitch are the odometry's: the body z axis in W does not move.
    EXPECT_LT((g.pose(k).R().row(2) - c.odometry[k].R().row(2)).norm(), 1e-9);
    // The correction maps the odometry pose onto the estimate, and is a rotation about z.
    const Pose mapped = g.correction(k) * g.odometryPose(k);
    EXPECT_LT((mapped.p - g.pose(k).p).norm(), 1e-9);
    EXPECT_LT((mapped.R() - g.pose(k).R()).norm(), 1e-9);
    EXPECT_LT((g.correction(k).R() * Vec3::UnitZ() - Vec3::UnitZ()).norm(), 1e-9);
  }
  // Node 0 holds the gauge.
  EXPECT_LT((g.pose(0).p - c.odometry[0].p).norm(), 1e-12);
}

TEST(PoseGraph, AWrongLoopEdgeIsDampedByTheRobustLoss) {
  const int n = 60;
  const Circle c = makeCircle(n, 0.0, Vec3::Zero());  // perfect odometry
  auto lastError = [&](double huber) {
    PoseGraph g;
    for (const Pose& p : c.odometry) g.addNode(p);
    for (std::size_t k = 1; k < c.odometry.size(); ++k)
      for (std::size_t i = (k >= 4 ? k - 4 : 0); i < k; ++i) g.addEdge(g.odometryEdge(i, k, 0.01, 1e-3));
    const std::size_t last = static_cast<std::size_t>(n);
    // A false loop: 1 m off.
    g.addEdge(g.loopEdge(0, last, Pose(Mat3::Identity(), Vec3(1.0, 0.0, 0.0)) * (c.truth[0].inverse() * c.truth[last]),
                         0.01, 1e-3));
    PoseGraphOptions o;
    o.loop_huber = huber;
    EXPECT_TRUE(g.optimise(o));
    return (g.pose(last).p - c.truth[last].p).norm();
  };
  const double plain = lastError(0.0), robust = lastError(1.0);
  EXPECT_GT(plain, 0.3);
  EXPECT_LT(robust, 0.2 * plain);
}

TEST(PoseGraph, ASolveOfTheNewestNodesHoldsTheOlderOnes) {
  const int n = 60;
  const Circle c = makeCircle(n, 0.003, Vec3(0.004, -0.002, 0.001));
  const std::size_t last = static_cast<std::size_t>(n);
  auto build = [&]() {
    PoseGraph g;
    for (const Pose& p : c.odometry) g.addNode(p);
    for (std::size_t k = 1; k < c.odometry.size(); ++k)
      for (std::size_t i = (k >= 4 ? k - 4 : 0); i < k; ++i) g.addEdge(g.odometryEdge(i, k, 0.01, 1e-3));
    g.addEdge(g.loopEdge(0, last, c.truth[0].inverse() * c.truth[last], 1e-3, 1e-4));
    return g;
  };
  PoseGraph whole = build(), window = build();
  ASSERT_TRUE(whole.optimise(PoseGraphOptions{}));
  PoseGraphOptions o;
  o.first_free_node = 40;
  ASSERT_TRUE(window.optimise(o));
  // The held nodes are exactly the odometry; the free ones take the loop's correction, bending 20 nodes instead of
  // 60 (so the newest one is pulled as close, but its neighbours less smoothly).
  for (std::size_t k = 0; k < o.first_free_node; ++k) EXPECT_EQ((window.pose(k).p - c.odometry[k].p).norm(), 0.0);
  const double drift = (c.odometry[last].p - c.truth[last].p).norm();
  EXPECT_LT((window.pose(last).p - c.truth[last].p).norm(), 0.1 * drift);
  EXPECT_GT((window.pose(40).p - c.odometry[40].p).norm(), 1e-4);
  // Solved again as a whole, it reaches the whole solve (to the solver's tolerance: 0.1 mm against 0.3 m of drift).
  ASSERT_TRUE(window.optimise(PoseGraphOptions{}));
  for (std::size_t k = 0; k <= last; ++k) EXPECT_LT((window.pose(k).p - whole.pose(k).p).norm(), 1e-4) << k;
}

TEST(PoseGraph, EdgesMeasureTheOdometryWhateverTheEstimatesWhenAdded) {
  // As the loop closer builds it: nodes added one by one at the latest correction, a solve after each loop; the
  // later loops reach nodes that the first one corrected. An edge is a measurement: the graph must end where the
  // same nodes and edges added at once end. (Edges taken against the nodes' estimates instead of their odometry
  // were off by the old node's correction: on a 10 min flight the final headings missed the loops by 0.4 deg.)
  const int per_lap = 60, n = 110;
  std::vector<Pose> truth, odometry;
  for (int k = 0; k <= n; ++k) {
    const double a = 2.0 * M_PI * k / per_lap;
    truth.push_back(tilted(a + M_PI / 2, Vec3(3.0 * std::cos(a), 3.0 * std::sin(a), 1.0 + 0.1 * std::sin(3.0 * a))));
  }
  odometry.push_back(truth[0]);
  for (int k = 1; k <= n; ++k) {
    const Pose d = truth[static_cast<std::size_t>(k - 1)].inverse() * truth[static_cast<std::size_t>(k)];
    const Pose next = odometry.back() * Pose(Mat3(d.R()), Vec3(d.p + Vec3(0.004, -0.002, 0.001)));
    odometry.push_back(Pose(Mat3(rotZ(0.003) * next.R()), next.p));
  }
  const std::vector<std::pair<std::size_t, std::size_t>> loops = {{0, 60}, {20, 80}, {40, 100}, {45, 105}};
  const auto addOdometryEdges = [&](PoseGraph* g, std::size_t k) {
    for (std::size_t i = (k >= 4 ? k - 4 : 0); i < k; ++i) g->addEdge(g->odometryEdge(i, k, 0.01, 1e-3));
  };
  const auto loopEdge = [&](const PoseGraph& g, std::size_t i, std::size_t k) {
    return g.loopEdge(i, k, truth[i].inverse() * truth[k], 1e-3, 1e-4);
  };
  PoseGraph batch;
  for (std::size_t k = 0; k <= static_cast<std::size_t>(n); ++k) {
    batch.addNode(odometry[k]);
    addOdometryEdges(&batch, k);
  }
  for (const auto& [i, k] : loops) batch.addEdge(loopEdge(batch, i, k));
  ASSERT_TRUE(batch.optimise(PoseGraphOptions{}));

  PoseGraph online;
  for (std::size_t k = 0; k <= static_cast<std::size_t>(n); ++k) {
    const Pose correction = k > 0 ? online.correction(k - 1) : Pose::identity();
    online.addNode(odometry[k]);
    online.setEstimate(k, correction * odometry[k]);
    addOdometryEdges(&online, k);
    for (const auto& [i, j] : loops) {
      if (j != k) continue;
      online.addEdge(loopEdge(online, i, k));
      ASSERT_TRUE(online.optimise(PoseGraphOptions{}));
    }
  }
  ASSERT_TRUE(online.optimise(PoseGraphOptions{}));  // as the loop closer's flush, for the nodes after the last loop
  // The first solve corrected node 20's heading by several degrees before the second loop reached it.
  EXPECT_GT(yawError(online.pose(20), online.odometryPose(20)), 0.02);
  for (std::size_t k = 0; k <= static_cast<std::size_t>(n); ++k) {
    // To the solvers' tolerance (they start from different estimates).
    EXPECT_LT((online.pose(k).p - batch.pose(k).p).norm(), 1e-3) << k;
    EXPECT_LT(yawError(online.pose(k), batch.pose(k)), 3e-4) << k;
  }
  // And the loops correct the drift (the odometry's heading is 0.33 rad off by then).
  EXPECT_LT(yawError(online.pose(105), truth[105]), 0.2 * yawError(odometry[105], truth[105]));
}

TEST(PoseGraph, RemovingTheNewestNodeRemovesItsEdges) {
  const Circle c = makeCircle(10, 0.0, Vec3::Zero());
  PoseGraph g;
  for (std::size_t k = 0; k < c.odometry.size(); ++k) {
    g.addNode(c.odometry[k]);
    if (k > 0) g.addEdge(g.odometryEdge(k - 1, k, 0.01, 1e-3));
  }
  g.addEdge(g.loopEdge(0, 10, c.truth[0].inverse() * c.truth[10], 1e-3, 1e-4));
  ASSERT_EQ(g.edges().size(), 11u);
  g.removeLastNode();
  EXPECT_EQ(g.size(), 10u);
  ASSERT_EQ(g.edges().size(), 9u);
  for (const PoseGraphEdge& e : g.edges()) EXPECT_LT(std::max(e.i, e.j), 10u);
  // A node added now takes index 10 again, with edges to the remaining ones.
  EXPECT_EQ(g.addNode(c.odometry[10]), 10u);
  g.addEdge(g.odometryEdge(9, 10, 0.01, 1e-3));
  EXPECT_TRUE(g.optimise(PoseGraphOptions{}));
  EXPECT_LT((g.pose(10).p - c.odometry[10].p).norm(), 1e-9);
}

}  // namespace
}  // namespace linnet

namespace linnet {
namespace {

// Camera looking along the body's x axis (camera z = body x, camera x = -body y, camera y = -body z).
Pose bodyToCamera() {
  Mat3 R;
  R.col(0) = Vec3(0.0, -1.0, 0.0);
  R.col(1) = Vec3(0.0, 0.0, -1.0);
  R.col(2) = Vec3(1.0, 0.0, 0.0);
  return Pose(R, Vec3::Zero());
}

Vec2 projectNormalised(const Pose& T_W_C, const Vec3& p_W) {
  const Vec3 p = T_W_C.inverse() * p_W;
  return p.head<2>() / p.z();
}

// Lines on a wall ahead of the circle's start (the body at (3, 0, 1) heading +y), seen at the start and again at the
// end of the loop: a drifting odometry with line sightings from both passes, and no loop edge.
struct TwoPasses {
  Circle c;
  std::vector<std::pair<Vec3, Vec3>> lines;
  std::vector<GraphLine> graph_lines;
};

// By default a drift of a few centimetres and about a degree: what remains after the place-recognition loops.
TwoPasses twoPasses(int n, double yaw_drift = 0.0003, const Vec3& shift = Vec3(0.0006, -0.0003, 0.0002)) {
  TwoPasses t;
  t.c = makeCircle(n, yaw_drift, shift);
  for (double x : {2.0, 2.5, 3.0, 3.5, 4.0}) t.lines.push_back({Vec3(x, 2.5, 0.2), Vec3(x, 2.5, 1.8)});
  for (double z : {0.3, 1.0, 1.7}) t.lines.push_back({Vec3(1.5, 2.5, z), Vec3(4.5, 2.5, z + 0.1)});
  t.lines.push_back({Vec3(2.5, 1.5, 0.0), Vec3(3.5, 2.3, 0.0)});  // on the floor, oblique
  const Pose T_B_C = bodyToCamera();
  const Pose T_B_C1 = T_B_C * Pose(Mat3::Identity(), Vec3(0.11, 0.0, 0.0));  // a stereo pair's right camera
  std::vector<std::size_t> seen;
  for (std::size_t k = 0; k <= 5; ++k) seen.push_back(k);
  for (std::size_t k = static_cast<std::size_t>(n) - 5; k <= static_cast<std::size_t>(n); ++k) seen.push_back(k);
  for (const auto& [a, b] : t.lines) {
    GraphLine g;
    const Vec6 L = normalisePlucker(pluckerFromPoints(a, b));
    for (int j = 0; j < 6; ++j) g.L[static_cast<std::size_t>(j)] = L[j];
    for (std::size_t k : seen)
      for (const Pose& T_B_Ci : {T_B_C, T_B_C1}) {
        const Pose cam_true = t.c.truth[k] * T_B_Ci;
        if ((cam_true.inverse() * a).z() < 0.3 || (cam_true.inverse() * b).z() < 0.3) continue;  // not in view
        GraphLine::Sighting s;
        s.node = k;
        s.T_Wo_C = t.c.odometry[k] * T_B_Ci;
        s.s = projectNormalised(cam_true, a + 0.1 * (b - a));
        s.e = projectNormalised(cam_true, a + 0.9 * (b - a));
        g.sightings.push_back(s);
      }
    t.graph_lines.push_back(g);
  }
  return t;
}

// Consecutive keyframes linked by their odometry, with sigmas about its per-step error.
void addOdometryEdges(PoseGraph* g, const Circle& c) {
  for (const Pose& p : c.odometry) g->addNode(p);
  for (std::size_t k = 1; k < c.odometry.size(); ++k) g->addEdge(g->odometryEdge(k - 1, k, 0.002, 5e-4));
}

TEST(PoseGraphWithLines, LinesSeenOnTwoPassesCloseTheLoop) {
  const int n = 60;
  TwoPasses t = twoPasses(n);
  PoseGraph g;
  addOdometryEdges(&g, t.c);
  const std::size_t last = static_cast<std::size_t>(n);
  const double drift_before = (t.c.odometry[last].p - t.c.truth[last].p).norm();
  const double yaw_before = yawError(t.c.odometry[last], t.c.truth[last]);
  ASSERT_GT(drift_before, 0.02);
  ASSERT_GT(yaw_before, 0.01);
  // The lines start 5 cm and 1 deg off.
  for (GraphLine& l : t.graph_lines) {
    const Vec6 L = transformPlucker(Pose(expSO3(Vec3(0.0, 0.0, 0.017)), Vec3(0.05, 0.0, 0.0)),
                                    Eigen::Map<const Vec6>(l.L.data()));
    for (int j = 0; j < 6; ++j) l.L[static_cast<std::size_t>(j)] = L[j];
  }
  ASSERT_TRUE(g.optimise(PoseGraphOptions{}, &t.graph_lines, GraphLineOptions{}));
  // The end of the loop is pulled towards the start's lines. The lines are seen from eleven neighbouring keyframes
  // (the end of the loop and its start), so the solve spreads the jump over both arcs rather than closing it as a
  // loop edge over the whole circle would: well below the odometry's error, not to zero.
  EXPECT_LT((g.pose(last).p - t.c.truth[last].p).norm(), 0.4 * drift_before);
  EXPECT_LT(yawError(g.pose(last), t.c.truth[last]), 0.5 * yaw_before);
  // The lines, 5 cm off at the start, come within a few centimetres of the true ones, unit-norm.
  for (std::size_t i = 0; i < t.lines.size(); ++i) {
    const Vec6 L = Eigen::Map<const Vec6>(t.graph_lines[i].L.data());
    EXPECT_NEAR(L.norm(), 1.0, 1e-9);
    EXPECT_LT(pluckerPointDistance(L, t.lines[i].first), 0.05) << i;
    EXPECT_LT(pluckerPointDistance(L, t.lines[i].second), 0.05) << i;
  }
  // Roll and pitch stay the odometry's.
  for (std::size_t k = 0; k <= last; ++k)
    EXPECT_LT((g.pose(k).R().row(2) - t.c.odometry[k].R().row(2)).norm(), 1e-9);
}

TEST(PoseGraphWithLines, ConsistentLinesAndOdometryStayPut) {
  // No drift: the odometry is the truth and the lines are exact; the solve keeps everything.
  const int n = 40;
  TwoPasses t = twoPasses(n, 0.0, Vec3::Zero());
  const std::vector<GraphLine> before = t.graph_lines;
  PoseGraph g;
  addOdometryEdges(&g, t.c);
  ASSERT_TRUE(g.optimise(PoseGraphOptions{}, &t.graph_lines, GraphLineOptions{}));
  for (std::size_t k = 0; k < t.c.truth.size(); ++k) EXPECT_LT((g.pose(k).p - t.c.truth[k].p).norm(), 1e-7);
  for (std::size_t i = 0; i < before.size(); ++i) {
    Vec6 a = Eigen::Map<const Vec6>(before[i].L.data()), b = Eigen::Map<const Vec6>(t.graph_lines[i].L.data());
    if (a.dot(b) < 0.0) b = -b;
    EXPECT_LT((a - b).norm(), 1e-7);
  }
}

TEST(PoseGraphWithLines, WithoutLinesItIsThePlainSolve) {
  const Circle c = makeCircle(30, 0.002, Vec3(0.01, 0.0, 0.0));
  PoseGraph a, b;
  addOdometryEdges(&a, c);
  addOdometryEdges(&b, c);
  a.addEdge(a.loopEdge(0, 30, c.truth[0].inverse() * c.truth[30], 1e-3, 1e-4));
  b.addEdge(b.loopEdge(0, 30, c.truth[0].inverse() * c.truth[30], 1e-3, 1e-4));
  std::vector<GraphLine> none;
  ASSERT_TRUE(a.optimise(PoseGraphOptions{}));
  ASSERT_TRUE(b.optimise(PoseGraphOptions{}, &none, GraphLineOptions{}));
  for (std::size_t k = 0; k <= 30; ++k) EXPECT_EQ((a.pose(k).p - b.pose(k).p).norm(), 0.0);
}

}  // namespace
}  // namespace linnet

namespace linnet {
namespace {

TEST(PoseGraphWithLines, PerturbedEstimatesReturnToTheConsistentSolution) {
  // Lines exact (zero cost at the truth); the second pass's estimates start 3 cm and 0.6 deg off, and only the
  // lines seen from both passes and from node 0 (held) tie them.
  const int n = 40;
  TwoPasses t = twoPasses(n, 0.0, Vec3::Zero());
  PoseGraph g;
  for (const Pose& p : t.c.odometry) g.addNode(p);  // no odometry edges: only the lines can bring them back
  for (std::size_t k = static_cast<std::size_t>(n) - 5; k <= static_cast<std::size_t>(n); ++k)
    g.setEstimate(k, Pose(Mat3(rotZ(0.01) * t.c.truth[k].R()), Vec3(t.c.truth[k].p + Vec3(0.02, -0.02, 0.01))));
  ASSERT_TRUE(g.optimise(PoseGraphOptions{}, &t.graph_lines, GraphLineOptions{}));
  for (std::size_t k = static_cast<std::size_t>(n) - 5; k <= static_cast<std::size_t>(n); ++k) {
    // Within a few millimetres: the lines, 2.5 m away and seen over 1.5 m, leave a shallow valley.
    EXPECT_LT((g.pose(k).p - t.c.truth[k].p).norm(), 0.004) << k;
    EXPECT_LT(yawError(g.pose(k), t.c.truth[k]), 1e-3) << k;
  }
}

}  // namespace
}  // namespace linnet
