#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "linnet/core/error.h"
#include "linnet/loop/place_matcher.h"
#include "loop_test_scene.h"

namespace linnet {
namespace {

// Random 32-byte descriptors.
cv::Mat randomDescriptors(int n, std::mt19937& rng) {
  cv::Mat d(n, 32, CV_8U);
  std::uniform_int_distribution<int> byte(0, 255);
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < 32; ++c) d.at<unsigned char>(r, c) = static_cast<unsigned char>(byte(rng));
  return d;
}

// An old keyframe's 2D corners and a new keyframe's 3D points of the same scene: `n` shared points (same
// descriptor), `outliers` of them matched to a wrong corner.
void syntheticPair(const Pose& T_Cold_Cnew, int n, int outliers, PlaceFeatures* old_kf, PlaceFeatures* new_kf) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(2.0, 6.0);
  const cv::Mat desc = randomDescriptors(n, rng);
  for (int i = 0; i < n; ++i) {
    const double z = depth(rng);
    const Vec3 p_new(u(rng) * 0.6 * z, u(rng) * 0.4 * z, z);
    const Vec3 p_old = T_Cold_Cnew * p_new;
    new_kf->p_C.push_back(p_new);
    new_kf->descriptors_3d.push_back(desc.row(i));
    Vec2 uv = p_old.head<2>() / p_old.z();
    if (i < outliers) uv += Vec2(0.05 + 0.01 * i, -0.04);  // a wrong corner with the same descriptor
    old_kf->uv.push_back(uv);
    old_kf->descriptors_2d.push_back(desc.row(i));
  }
  // Unrelated corners in the old keyframe.
  const cv::Mat other = randomDescriptors(3 * n, rng);
  for (int i = 0; i < 3 * n; ++i) {
    old_kf->uv.push_back(Vec2(u(rng) * 0.6, u(rng) * 0.4));
    old_kf->descriptors_2d.push_back(other.row(i));
  }
}

TEST(PlaceMatcher, RecoversTheRelativePoseDespiteWrongMatches) {
  const Pose T_Cold_Cnew(expSO3(Vec3(0.02, -0.25, 0.03)), Vec3(0.4, -0.05, 0.3));
  PlaceFeatures old_kf, new_kf;
  syntheticPair(T_Cold_Cnew, 80, 20, &old_kf, &new_kf);
  PlaceMatchOptions o;
  o.min_inliers = 30;
  const PlaceMatch m = matchPlaces(old_kf, new_kf, o);
  ASSERT_TRUE(m.ok);
  EXPECT_EQ(m.matches, 80);
  EXPECT_EQ(m.inliers, 60);
  EXPECT_LT((m.T_Cold_Cnew.p - T_Cold_Cnew.p).norm(), 1e-6);
  EXPECT_LT(logSO3(m.T_Cold_Cnew.q.conjugate() * T_Cold_Cnew.q).norm(), 1e-6);
}

TEST(PlaceMatcher, SolvesTheOtherWayWhenOnlyTheOldKeyframeHasDepth) {
  const Pose T_Cold_Cnew(expSO3(Vec3(0.0, 0.2, 0.0)), Vec3(-0.3, 0.0, 0.2));
  // Built as "new has depth", then swapped: the old keyframe has the 3D points, the new one the corners.
  PlaceFeatures a, b;
  syntheticPair(T_Cold_Cnew.inverse(), 60, 0, &a, &b);  // a: 2D corners seen from "new", b: 3D points of "old"
  PlaceFeatures old_kf = b, new_kf = a;
  PlaceMatchOptions o;
  o.min_inliers = 30;
  const PlaceMatch m = matchPlaces(old_kf, new_kf, o);
  ASSERT_TRUE(m.ok);
  EXPECT_LT((m.T_Cold_Cnew.p - T_Cold_Cnew.p).norm(), 1e-6);
}

// Monte Carlo over corner noise: the spread of the solved pose (perturbation R = exp(dtheta) R_true, t = t_true + dt)
// must match the covariance matchPlaces reports, solved from the new keyframe's points (`new_has_depth`) or, the
// other way round, from the old one's and inverted.
void checkCovariance(bool new_has_depth) {
  // A large rotation and baseline, so that inverting the pose mixes its covariance's axes.
  const Pose T_Cold_Cnew(expSO3(Vec3(0.1, -0.5, 0.1)), Vec3(0.9, -0.1, 0.6));
  PlaceFeatures old_kf, new_kf;
  if (new_has_depth) {
    syntheticPair(T_Cold_Cnew, 40, 0, &old_kf, &new_kf);
  } else {
    syntheticPair(T_Cold_Cnew.inverse(), 40, 0, &new_kf, &old_kf);
  }
  PlaceFeatures& corners = new_has_depth ? old_kf : new_kf;
  const std::vector<Vec2> clean = corners.uv;
  PlaceMatchOptions o;
  o.min_inliers = 20;
  o.ransac_px = 5.0;
  const double sigma = 1.0 / o.focal_px;  // 1 px
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, sigma);
  const int trials = 400;
  Eigen::Matrix<double, 6, 6> predicted = Eigen::Matrix<double, 6, 6>::Zero();
  std::vector<Eigen::Matrix<double, 6, 1>> errors;
  for (int k = 0; k < trials; ++k) {
    for (int i = 0; i < 40; ++i) corners.uv[static_cast<std::size_t>(i)] = clean[static_cast<std::size_t>(i)] + Vec2(noise(rng), noise(rng));
    const PlaceMatch m = matchPlaces(old_kf, new_kf, o);
    ASSERT_TRUE(m.ok);
    ASSERT_GE(m.inliers, 36);
    Eigen::Matrix<double, 6, 1> e;
    e << logSO3(m.T_Cold_Cnew.q * T_Cold_Cnew.q.conjugate()), m.T_Cold_Cnew.p - T_Cold_Cnew.p;
    errors.push_back(e);
    predicted += m.covariance / trials;
  }
  // Mahalanobis: E[e^T C^-1 e] = 6 for a right covariance (a 20 % band holds for 400 trials).
  const Eigen::Matrix<double, 6, 6> info = predicted.inverse();
  double mahalanobis = 0.0;
  for (const auto& e : errors) mahalanobis += e.dot(info * e) / trials;
  EXPECT_NEAR(mahalanobis, 6.0, 1.2) << (new_has_depth ? "new" : "old") << " keyframe with depth";
  // And per axis: the predicted standard deviations against the empirical ones.
  for (int a = 0; a < 6; ++a) {
    double var = 0.0;
    for (const auto& e : errors) var += e(a) * e(a) / trials;
    EXPECT_NEAR(std::sqrt(var / predicted(a, a)), 1.0, 0.15) << "axis " << a;
  }
}

TEST(PlaceMatcher, CovarianceMatchesTheSpreadOfTheSolvedPose) {
  checkCovariance(true);
  checkCovariance(false);
}

// Two keyframes that both hold the same n points: 3D in each camera (depth scaled by 1 + depth_noise * N(0, 1),
// independently in each keyframe, as two estimates of one landmark are), and exact corners.
void bothHaveDepth(const Pose& T_Cold_Cnew, int n, double depth_noise, std::mt19937& rng, PlaceFeatures* old_kf,
                   PlaceFeatures* new_kf) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(2.0, 8.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const cv::Mat desc = randomDescriptors(n, rng);
  *old_kf = PlaceFeatures();
  *new_kf = PlaceFeatures();
  for (int i = 0; i < n; ++i) {
    const double z = depth(rng);
    const Vec3 p_new(u(rng) * 0.6 * z, u(rng) * 0.4 * z, z);
    const Vec3 p_old = T_Cold_Cnew * p_new;
    for (auto [kf, p] : {std::pair{new_kf, p_new}, std::pair{old_kf, p_old}}) {
      kf->p_C.push_back(p * (1.0 + depth_noise * g(rng)));
      kf->descriptors_3d.push_back(desc.row(i));
      kf->uv.push_back(p.head<2>() / p.z());
      kf->descriptors_2d.push_back(desc.row(i));
    }
  }
}

// Two-way refinement: exact on exact points, and with both keyframes' depths off by 1 % its translation error is
// clearly below the one-way PnP's (about 1 / sqrt 2 of it: each keyframe's landmark errors no longer set the pose
// alone).
TEST(PlaceMatcher, TwoWayRefinementUsesBothKeyframesPoints) {
  const Pose T_Cold_Cnew(expSO3(Vec3(0.03, -0.3, 0.02)), Vec3(0.5, -0.05, 0.25));
  PlaceMatchOptions one_way, two_way;
  one_way.min_inliers = two_way.min_inliers = 20;
  two_way.two_way = true;
  std::mt19937 rng(21);
  PlaceFeatures old_kf, new_kf;
  bothHaveDepth(T_Cold_Cnew, 40, 0.0, rng, &old_kf, &new_kf);
  const PlaceMatch exact = matchPlaces(old_kf, new_kf, two_way);
  ASSERT_TRUE(exact.ok);
  EXPECT_EQ(exact.reverse_inliers, 40);
  EXPECT_LT((exact.T_Cold_Cnew.p - T_Cold_Cnew.p).norm(), 1e-9);
  EXPECT_LT(logSO3(exact.T_Cold_Cnew.q.conjugate() * T_Cold_Cnew.q).norm(), 1e-9);
  EXPECT_EQ(matchPlaces(old_kf, new_kf, one_way).reverse_inliers, 0);

  double sq_one = 0.0, sq_two = 0.0;
  constexpr int kTrials = 100;
  for (int k = 0; k < kTrials; ++k) {
    bothHaveDepth(T_Cold_Cnew, 40, 0.01, rng, &old_kf, &new_kf);
    const PlaceMatch a = matchPlaces(old_kf, new_kf, one_way), b = matchPlaces(old_kf, new_kf, two_way);
    ASSERT_TRUE(a.ok && b.ok);
    ASSERT_GT(b.reverse_inliers, 0);
    ASSERT_TRUE(b.covariance.allFinite());
    EXPECT_GT(b.covariance.diagonal().minCoeff(), 0.0);
    sq_one += (a.T_Cold_Cnew.p - T_Cold_Cnew.p).squaredNorm();
    sq_two += (b.T_Cold_Cnew.p - T_Cold_Cnew.p).squaredNorm();
  }
  EXPECT_LT(std::sqrt(sq_two / kTrials), 0.8 * std::sqrt(sq_one / kTrials))
      << "one-way " << std::sqrt(sq_one / kTrials) << " m, two-way " << std::sqrt(sq_two / kTrials) << " m";
}

TEST(PlaceMatcher, RejectsTooFewMatches) {
  PlaceFeatures old_kf, new_kf;
  syntheticPair(Pose::identity(), 20, 0, &old_kf, &new_kf);
  PlaceMatchOptions o;
  o.min_inliers = 25;
  EXPECT_FALSE(matchPlaces(old_kf, new_kf, o).ok);
  // Unrelated descriptors: nothing passes the distance and ratio tests.
  std::mt19937 rng(3);
  new_kf.descriptors_3d = randomDescriptors(new_kf.descriptors_3d.rows, rng);
  const PlaceMatch m = matchPlaces(old_kf, new_kf, o);
  EXPECT_FALSE(m.ok);
  EXPECT_LT(m.matches, 5);
}

// Each true corner of the old keyframe gets a distractor elsewhere in the image with a closer descriptor (the true
// one differs by one bit), so that matching by descriptor alone picks the distractors.
void addDistractors(int n, PlaceFeatures* old_kf) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> angle(0.0, 2.0 * M_PI), radius(0.12, 0.3);
  for (int i = 0; i < n; ++i) {
    const cv::Mat exact = old_kf->descriptors_2d.row(i).clone();
    old_kf->descriptors_2d.at<unsigned char>(i, 0) ^= 1;
    const double a = angle(rng), r = radius(rng);
    old_kf->uv.push_back(old_kf->uv[static_cast<std::size_t>(i)] + r * Vec2(std::cos(a), std::sin(a)));
    old_kf->descriptors_2d.push_back(exact);
  }
}

TEST(PlaceMatcher, GuidedMatchingAroundAPriorFindsTheLoopDescriptorsMiss) {
  const Pose T_Cold_Cnew(expSO3(Vec3(0.01, -0.2, 0.02)), Vec3(0.3, -0.05, 0.2));
  PlaceFeatures old_kf, new_kf;
  syntheticPair(T_Cold_Cnew, 40, 0, &old_kf, &new_kf);
  addDistractors(40, &old_kf);
  PlaceMatchOptions o;
  o.min_inliers = 20;
  EXPECT_FALSE(matchPlaces(old_kf, new_kf, o).ok) << "descriptors alone must pick the distractors";
  // A prior 2 cm and 0.5 deg off: the true corners are within the radius, the distractors (55-140 px away) not.
  o.prior_T_Cold_Cnew = Pose(expSO3(Vec3(0.0, 0.5 * M_PI / 180.0, 0.0)), Vec3(0.02, 0.0, 0.0)) * T_Cold_Cnew;
  o.guided_radius_px = 25.0;
  const PlaceMatch m = matchPlaces(old_kf, new_kf, o);
  ASSERT_TRUE(m.ok);
  EXPECT_EQ(m.inliers, 40);
  EXPECT_LT((m.T_Cold_Cnew.p - T_Cold_Cnew.p).norm(), 1e-6);
  EXPECT_LT(logSO3(m.T_Cold_Cnew.q.conjugate() * T_Cold_Cnew.q).norm(), 1e-6);
  // Off: the same as without a prior.
  o.guided_radius_px = 0.0;
  EXPECT_FALSE(matchPlaces(old_kf, new_kf, o).ok);
  // A prior far off (0.5 m) finds no loop.
  o.guided_radius_px = 25.0;
  o.prior_T_Cold_Cnew = Pose(Quat::Identity(), Vec3(0.5, 0.0, 0.0)) * T_Cold_Cnew;
  EXPECT_FALSE(matchPlaces(old_kf, new_kf, o).ok);
}

// `n` 3D segments in the new keyframe's cam0 (with random LBD descriptors) and the old keyframe's image lines of the
// same segments, each seen over a different part of the segment.
void syntheticLines(const Pose& T_Cold_Cnew, int n, PlaceFeatures* old_kf, PlaceFeatures* new_kf) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(2.0, 6.0), length(0.5, 1.5);
  for (int i = 0; i < n; ++i) {
    const double z = depth(rng);
    const Vec3 P0(u(rng) * 0.5 * z, u(rng) * 0.3 * z, z);
    const Vec3 P1 = P0 + length(rng) * Vec3(u(rng), u(rng), 0.3 * u(rng)).normalized();
    const LbdDescriptor desc = {rng(), rng(), rng(), rng()};
    new_kf->line_ids.push_back(i);
    new_kf->line_p_C.push_back({P0, P1});
    new_kf->line_desc.push_back(desc);
    new_kf->line_uv.push_back({Vec2::Zero(), Vec2::Zero()});
    const Vec3 A = T_Cold_Cnew * (P0 + 0.1 * (P1 - P0)), B = T_Cold_Cnew * (P0 + 0.8 * (P1 - P0));
    old_kf->line_ids.push_back(100 + i);
    old_kf->line_uv.push_back({A.head<2>() / A.z(), B.head<2>() / B.z()});
    old_kf->line_desc.push_back(desc);
    const Vec3 none = Vec3::Constant(std::numeric_limits<double>::quiet_NaN());
    old_kf->line_p_C.push_back({none, none});
  }
}

TEST(PlaceMatcher, LinesCloseALoopThatTooFewCornersCannot) {
  const Pose T_Cold_Cnew(expSO3(Vec3(0.01, -0.2, 0.02)), Vec3(0.3, -0.05, 0.2));
  PlaceFeatures old_kf, new_kf;
  syntheticPair(T_Cold_Cnew, 8, 0, &old_kf, &new_kf);
  syntheticLines(T_Cold_Cnew, 30, &old_kf, &new_kf);
  PlaceMatchOptions o;
  o.min_inliers = 15;
  o.guided_radius_px = 25.0;
  o.prior_T_Cold_Cnew = Pose(expSO3(Vec3(0.0, 0.5 * M_PI / 180.0, 0.0)), Vec3(0.02, 0.0, 0.0)) * T_Cold_Cnew;
  EXPECT_FALSE(matchPlaces(old_kf, new_kf, o).ok) << "8 corners are too few";
  o.use_lines = true;
  const PlaceMatch m = matchPlaces(old_kf, new_kf, o);
  ASSERT_TRUE(m.ok);
  EXPECT_EQ(m.inliers, 38);
  EXPECT_LT((m.T_Cold_Cnew.p - T_Cold_Cnew.p).norm(), 1e-6);
  EXPECT_LT(logSO3(m.T_Cold_Cnew.q.conjugate() * T_Cold_Cnew.q).norm(), 1e-6);
  EXPECT_TRUE(m.covariance.allFinite());
  // The other way round (only the old keyframe has 3D features): the same pose.
  const PlaceMatch back = matchPlacesWithLines(new_kf, old_kf, [&] {
    PlaceMatchOptions ob = o;
    ob.prior_T_Cold_Cnew = o.prior_T_Cold_Cnew->inverse();
    return ob;
  }());
  ASSERT_TRUE(back.ok);
  EXPECT_LT((back.T_Cold_Cnew.inverse().p - T_Cold_Cnew.p).norm(), 1e-6);
  // A prior far off (0.5 m) finds no loop.
  o.prior_T_Cold_Cnew = Pose(Quat::Identity(), Vec3(0.5, 0.0, 0.0)) * T_Cold_Cnew;
  EXPECT_FALSE(matchPlaces(old_kf, new_kf, o).ok);
}

TEST(PlaceMatcher, PlaceLinesTakeGivenDescriptorsOrComputeThem) {
  const test::WallScene scene;
  const cv::Mat image = scene.render(scene.cameraAt(Vec3(0.3, 0.0, 1.2), 0.1));
  std::vector<LineObservation> lines(3);
  for (int i = 0; i < 3; ++i) {
    lines[static_cast<std::size_t>(i)].id = 10 + i;
    lines[static_cast<std::size_t>(i)].ps0 = Vec2(100.0 + 60 * i, 120.0);
    lines[static_cast<std::size_t>(i)].pe0 = Vec2(140.0 + 60 * i, 300.0);
  }
  PlaceFeatures own, given;
  describePlaceLines(image, lines, LbdOptions{}, &own);
  ASSERT_EQ(own.line_desc.size(), 3u);
  for (const LineObservation& o : lines)
    EXPECT_EQ(own.line_desc[static_cast<std::size_t>(o.id - 10)],
              binarizeLbd(computeLbdFloat(image, LbdOptions{}, LineSegment{o.ps0, o.pe0})));
  std::vector<LbdDescriptor> tracker(3);
  for (std::size_t i = 0; i < 3; ++i) tracker[i].fill(0x0101010101010101ULL * (i + 1));
  describePlaceLines(image, lines, LbdOptions{}, &given, &tracker);
  EXPECT_EQ(given.line_desc, tracker);
  EXPECT_EQ(given.line_ids, own.line_ids);
  tracker.pop_back();
  PlaceFeatures wrong;
  EXPECT_THROW(describePlaceLines(image, lines, LbdOptions{}, &wrong, &tracker), UsageError);
}

TEST(PlaceMatcher, PlaceLinesTakeTheWindowLandmarksInTheCameraFrame) {
  PlaceFeatures f;
  f.line_ids = {3, 5, 8};
  f.line_uv.assign(3, {Vec2::Zero(), Vec2::Zero()});
  f.line_desc.assign(3, LbdDescriptor{});
  f.line_p_C.assign(3, {Vec3::Zero(), Vec3::Zero()});
  const Pose T_W_C(expSO3(Vec3(0.1, 0.2, -0.3)), Vec3(1.0, 2.0, 0.5));
  const Vec3 a_C(0.2, 0.1, 3.0), b_C(-0.4, 0.3, 2.5);
  std::vector<MapLine> window(3);
  window[0].id = 3;  // in front
  window[0].a = T_W_C * a_C;
  window[0].b = T_W_C * b_C;
  window[1].id = 4;  // not one of the keyframe's lines
  window[2].id = 8;  // one end behind the camera
  window[2].a = T_W_C * a_C;
  window[2].b = T_W_C * Vec3(0.0, 0.0, -1.0);
  setPlaceLines(window, T_W_C, &f);
  EXPECT_LT((f.line_p_C[0][0] - a_C).norm(), 1e-12);
  EXPECT_LT((f.line_p_C[0][1] - b_C).norm(), 1e-12);
  EXPECT_FALSE(f.line_p_C[1][0].allFinite()) << "no landmark for id 5";
  EXPECT_FALSE(f.line_p_C[2][0].allFinite()) << "behind the camera";
}

TEST(PlaceMatcher, DescribesTrackedCornersWithStereoDepthAndMoreCorners) {
  const test::WallScene scene;
  const Pose T_W_C = scene.cameraAt(Vec3(0.3, 0.0, 1.2), 0.1);
  const cv::Mat image = scene.render(T_W_C);
  const std::vector<PointObservation> tracked = scene.trackedCorners(image, T_W_C, 120);
  ASSERT_GE(tracked.size(), 100u);
  PlaceDescription d;
  d.corners = 300;
  const PlaceFeatures f = describePlace(image, *scene.camera, tracked, scene.T_C1_C0, d);
  EXPECT_GE(f.p_C.size(), 90u);
  EXPECT_EQ(f.descriptors_3d.rows, static_cast<int>(f.p_C.size()));
  EXPECT_GE(f.uv.size(), 300u);
  EXPECT_EQ(f.descriptors_2d.rows, static_cast<int>(f.uv.size()));
  // Stereo depths: every point lies on the wall.
  for (const Vec3& p_C : f.p_C) EXPECT_NEAR((T_W_C * p_C).y(), scene.wall_y, 0.02 * scene.wall_y);
}

TEST(PlaceMatcher, CornersFoundByTheTrackerGiveTheSameDescription) {
  const test::WallScene scene;
  const Pose T_W_C = scene.cameraAt(Vec3(0.3, 0.0, 1.2), 0.1);
  const cv::Mat image = scene.render(T_W_C);
  const std::vector<PointObservation> tracked = scene.trackedCorners(image, T_W_C, 120);
  PlaceDescription d;
  d.corners = 300;
  // Replenishment's first FAST round on the whole image, at the place description's threshold.
  PointDetectorParams p;
  p.fast_threshold = d.fast_threshold;
  cv::Mat mask(image.size(), CV_8UC1, cv::Scalar(255));
  FastCorners found;
  detectCorners(image, &mask, 50, p, &found);
  ASSERT_EQ(found.threshold, d.fast_threshold);
  ASSERT_GT(found.keypoints.size(), 300u) << "the quota must not be met before the corners matter";
  const PlaceFeatures own = describePlace(image, *scene.camera, tracked, scene.T_C1_C0, d);
  const PlaceFeatures given = describePlace(image, *scene.camera, tracked, scene.T_C1_C0, d, &found);
  ASSERT_EQ(given.uv.size(), own.uv.size());
  for (std::size_t i = 0; i < own.uv.size(); ++i) EXPECT_EQ(given.uv[i], own.uv[i]) << i;
  EXPECT_EQ(cv::norm(given.descriptors_2d, own.descriptors_2d, cv::NORM_HAMMING), 0.0);
  // Corners of another threshold are not the description's: it searches again.
  found.threshold = d.fast_threshold + 5;
  found.keypoints.resize(10);
  const PlaceFeatures other = describePlace(image, *scene.camera, tracked, scene.T_C1_C0, d, &found);
  ASSERT_EQ(other.uv.size(), own.uv.size());
  EXPECT_EQ(cv::norm(other.descriptors_2d, own.descriptors_2d, cv::NORM_HAMMING), 0.0);
}

TEST(PlaceMatcher, MatchesTwoViewsOfTheSamePlace) {
  const test::WallScene scene;
  const Pose T_W_Cold = scene.cameraAt(Vec3(0.0, 0.0, 1.2), 0.0);
  const Pose T_W_Cnew = scene.cameraAt(Vec3(0.35, 0.4, 1.1), 0.12);
  PlaceDescription d;
  const cv::Mat img_old = scene.render(T_W_Cold), img_new = scene.render(T_W_Cnew);
  const PlaceFeatures f_old =
      describePlace(img_old, *scene.camera, scene.trackedCorners(img_old, T_W_Cold, 150), scene.T_C1_C0, d);
  const PlaceFeatures f_new =
      describePlace(img_new, *scene.camera, scene.trackedCorners(img_new, T_W_Cnew, 150), scene.T_C1_C0, d);
  const PlaceMatch m = matchPlaces(f_old, f_new, PlaceMatchOptions{});
  ASSERT_TRUE(m.ok) << m.matches << " matches, " << m.inliers << " inliers";
  const Pose truth = T_W_Cold.inverse() * T_W_Cnew;
  EXPECT_LT((m.T_Cold_Cnew.p - truth.p).norm(), 0.03);
  EXPECT_LT(logSO3(m.T_Cold_Cnew.q.conjugate() * truth.q).norm(), 0.01);
}

}  // namespace
}  // namespace linnet
