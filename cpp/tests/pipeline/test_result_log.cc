#include "linnet/pipeline/result_log.h"

#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

namespace linnet {
namespace {

Pose randomPose(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Pose(Quat(n(rng), n(rng), n(rng), n(rng)), Vec3(n(rng), n(rng), n(rng)));
}

bool bitEqual(const Pose& a, const Pose& b) {
  return std::memcmp(a.q.coeffs().data(), b.q.coeffs().data(), 4 * sizeof(double)) == 0 &&
         std::memcmp(a.p.data(), b.p.data(), 3 * sizeof(double)) == 0;
}

bool bitEqual(const Vec3& a, const Vec3& b) { return std::memcmp(a.data(), b.data(), 3 * sizeof(double)) == 0; }

// A frame's result the way the System fills it: random odometry, a calibration that changes for the first frames
// only, and (when `C` is given) the corrected pose made from it.
FrameResult makeResult(std::mt19937& rng, int i, const std::optional<Pose>& C) {
  std::uniform_real_distribution<double> u(0.0, 20.0);
  FrameResult r;
  EstimatorOutput& e = r.estimate;
  e.t = 1000000000LL + 50000000LL * i;
  e.status = i % 7 == 3 ? TrackingStatus::kLost : TrackingStatus::kTracking;
  e.has_pose = i >= 2;
  e.T_W_B = randomPose(rng);
  e.v_W = Vec3(u(rng), -u(rng), u(rng));
  e.b_a = Vec3(u(rng), u(rng), u(rng)) * 1e-3;
  e.b_g = Vec3(u(rng), u(rng), u(rng)) * 1e-4;
  e.keyframe = i % 2 == 0;
  e.num_points = 100 + i;
  e.num_lines = 40 + i;
  e.reidentified_lines = i % 3;
  e.line_ms = u(rng);
  e.solver_ms = u(rng);
  e.reinitialisations = i / 10;
  if (i < 5) {
    e.T_B_R = randomPose(rng);
    e.S_C1 = randomPose(rng);
    e.time_offset_s = 1e-3 * i;
  } else {
    e.T_B_R = Pose(Quat(1.0, 0.01, 0.0, 0.0), Vec3(0.001, 0.0, 0.0));
    e.S_C1 = Pose(Quat(1.0, 0.0, 0.02, 0.0), Vec3(0.0, 0.002, 0.0));
    e.time_offset_s = 0.003;
  }
  e.solve_ms = u(rng);
  r.T_W_B = e.T_W_B;
  r.v_W = e.v_W;
  if (C) {
    r.T_W_B = *C * e.T_W_B;
    r.v_W = C->q * e.v_W;
  }
  r.tracked_points = 150 + i;
  r.stereo_points = 120 + i;
  r.tracked_lines = 60 + i;
  r.point_ms = u(rng);
  r.line_ms = u(rng);
  r.frontend_ms = u(rng);
  r.backend_ms = u(rng);
  r.line_backend_ms = e.line_ms;
  r.solver_ms = e.solver_ms;
  r.point_cpu_ms = u(rng);
  r.line_cpu_ms = u(rng);
  r.backend_cpu_ms = u(rng);
  r.loop_cpu_ms = u(rng);
  r.rss_mb = 100.0 + u(rng);
  return r;
}

// a: from the log, b: as pushed.
void expectSame(const FrameResult& a, const FrameResult& b) {
  const EstimatorOutput &x = a.estimate, &y = b.estimate;
  EXPECT_EQ(x.t, y.t);
  EXPECT_EQ(x.status, y.status);
  EXPECT_EQ(x.has_pose, y.has_pose);
  EXPECT_TRUE(bitEqual(x.T_W_B, y.T_W_B));
  EXPECT_TRUE(bitEqual(x.v_W, y.v_W));
  EXPECT_TRUE(bitEqual(x.b_a, y.b_a));
  EXPECT_TRUE(bitEqual(x.b_g, y.b_g));
  EXPECT_EQ(x.keyframe, y.keyframe);
  EXPECT_EQ(x.num_points, y.num_points);
  EXPECT_EQ(x.num_lines, y.num_lines);
  EXPECT_EQ(x.reidentified_lines, y.reidentified_lines);
  EXPECT_EQ(x.reinitialisations, y.reinitialisations);
  EXPECT_TRUE(bitEqual(x.T_B_R, y.T_B_R));
  EXPECT_TRUE(bitEqual(x.S_C1, y.S_C1));
  EXPECT_EQ(x.time_offset_s, y.time_offset_s);
  EXPECT_TRUE(bitEqual(a.T_W_B, b.T_W_B));
  EXPECT_TRUE(bitEqual(a.v_W, b.v_W));
  EXPECT_EQ(a.tracked_points, b.tracked_points);
  EXPECT_EQ(a.stereo_points, b.stereo_points);
  EXPECT_EQ(a.tracked_lines, b.tracked_lines);
  // Diagnostics in single precision.
  for (auto [p, q] : {std::pair{x.line_ms, y.line_ms}, {x.solver_ms, y.solver_ms}, {x.solve_ms, y.solve_ms},
                      {a.point_ms, b.point_ms}, {a.line_ms, b.line_ms}, {a.frontend_ms, b.frontend_ms},
                      {a.backend_ms, b.backend_ms}, {a.line_backend_ms, b.line_backend_ms},
                      {a.solver_ms, b.solver_ms}, {a.point_cpu_ms, b.point_cpu_ms}, {a.line_cpu_ms, b.line_cpu_ms},
                      {a.backend_cpu_ms, b.backend_cpu_ms}, {a.loop_cpu_ms, b.loop_cpu_ms}, {a.rss_mb, b.rss_mb}})
    EXPECT_EQ(p, static_cast<double>(static_cast<float>(q)));
}

TEST(ResultLog, GivesBackEveryResultWithItsCorrection) {
  std::mt19937 rng(3);
  ResultLog log;
  std::vector<FrameResult> pushed;
  std::vector<Pose> corrections = {Pose::identity(), randomPose(rng), randomPose(rng)};
  for (int i = 0; i < 40; ++i) {
    // No correction before frame 2 (no pose) and for frames 20-24 (loop closure off for them); the correction
    // changes at frames 10 and 30.
    std::optional<Pose> C;
    if (i >= 2 && (i < 20 || i >= 25)) C = corrections[i < 10 ? 0 : i < 30 ? 1 : 2];
    pushed.push_back(makeResult(rng, i, C));
    log.push(pushed.back(), C);
  }
  ASSERT_EQ(log.size(), pushed.size());
  for (std::size_t i = 0; i < pushed.size(); ++i) {
    SCOPED_TRACE(i);
    expectSame(log.at(i), pushed[i]);
  }
  // One block of records so far (256 of them), whatever the 40 results.
  EXPECT_LE(log.bytes(), 256 * 224 + 2000);
}

TEST(ResultLog, AFrameCostsItsRecordOnALongRun) {
  std::mt19937 rng(5);
  ResultLog log;
  const int n = 5000;  // 20 blocks of 256 records, the last one partly used
  for (int i = 0; i < n; ++i) log.push(makeResult(rng, i, std::nullopt), std::nullopt);
  ASSERT_EQ(log.size(), static_cast<std::size_t>(n));
  EXPECT_LE(log.bytes(), static_cast<std::size_t>(n) * 232);  // 224 bytes a record, the unused tail of one block
  EXPECT_EQ(log.at(n - 1).estimate.t, makeResult(rng, n - 1, std::nullopt).estimate.t);
  EXPECT_THROW(log.at(n), std::out_of_range);
}

TEST(ResultLog, RecorrectGivesEveryPosedFrameItsFinalCorrection) {
  std::mt19937 rng(4);
  ResultLog log;
  std::vector<FrameResult> pushed;
  for (int i = 0; i < 30; ++i) {
    const std::optional<Pose> C = i >= 2 ? std::optional<Pose>(randomPose(rng)) : std::nullopt;
    pushed.push_back(makeResult(rng, i, C));
    log.push(pushed.back(), C);
  }
  const Pose A = randomPose(rng), B = randomPose(rng);
  auto final = [&](Timestamp t) { return t < pushed[12].estimate.t ? A : B; };
  log.recorrect(final);
  for (std::size_t i = 0; i < pushed.size(); ++i) {
    SCOPED_TRACE(i);
    FrameResult want = pushed[i];
    if (want.estimate.has_pose) {
      const Pose C = final(want.estimate.t);
      want.T_W_B = C * want.estimate.T_W_B;
      want.v_W = C.q * want.estimate.v_W;
    }
    expectSame(log.at(i), want);
  }
}

}  // namespace
}  // namespace linnet
