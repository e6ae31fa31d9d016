// The loop closer's stored place descriptions (place_store.h): what comes back is the description to float precision,
// each 3D corner with its own descriptor, in less memory; and a loop matched on it is the same loop.
#include <gtest/gtest.h>

#include "linnet/loop/place_store.h"
#include "loop_test_scene.h"

namespace linnet {
namespace {

PlaceFeatures describedWall(const test::WallScene& scene, const Pose& T_W_C) {
  const cv::Mat image = scene.render(T_W_C);
  PlaceFeatures f = describePlace(image, *scene.camera, scene.trackedCorners(image, T_W_C, 150), scene.T_C1_C0,
                                  PlaceDescription{});
  // The odometry's positions for half the tracked corners (the others keep their stereo positions), 1 cm off.
  std::vector<Vec3> p_W(f.tracked_ids.size(), Vec3::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (std::size_t i = 0; i < p_W.size(); i += 2)
    if (f.tracked_stereo_p_C[i].allFinite()) p_W[i] = T_W_C * f.tracked_stereo_p_C[i] + Vec3(0.01, 0.0, 0.0);
  setPlaceDepths(p_W, T_W_C, &f);
  f.line_uv = {{Vec2(0.1, 0.2), Vec2(-0.3, 0.25)}};
  f.line_desc.resize(1);
  f.line_desc[0].fill(0x5A);
  f.line_p_C = {{Vec3(0.2, 0.4, 2.0), Vec3(-0.6, 0.5, 2.0)}};
  return f;
}

TEST(PlaceStore, GivesTheDescriptionBackToFloatPrecisionInLessMemory) {
  const test::WallScene scene;
  const PlaceFeatures f = describedWall(scene, test::WallScene::cameraAt(Vec3(0.2, 0.0, 1.2), 0.05));
  ASSERT_GE(f.p_C.size(), 50u);
  ASSERT_EQ(f.rows_3d.size(), f.p_C.size());
  const StoredPlace s = storePlace(f);
  EXPECT_TRUE(s.described());
  EXPECT_EQ(s.rows_3d.size(), f.p_C.size());
  EXPECT_TRUE(s.descriptors_3d.empty()) << "the 3D corners' descriptors are rows of the 2D set";
  const PlaceFeatures g = expandPlace(s);
  ASSERT_EQ(g.uv.size(), f.uv.size());
  ASSERT_EQ(g.p_C.size(), f.p_C.size());
  for (std::size_t i = 0; i < f.uv.size(); ++i) EXPECT_LT((g.uv[i] - f.uv[i]).norm(), 1e-7);
  for (std::size_t i = 0; i < f.p_C.size(); ++i) EXPECT_LT((g.p_C[i] - f.p_C[i]).norm(), 1e-6);
  ASSERT_EQ(g.descriptors_3d.rows, f.descriptors_3d.rows);
  EXPECT_EQ(cv::norm(g.descriptors_3d, f.descriptors_3d, cv::NORM_HAMMING), 0.0);
  EXPECT_EQ(cv::norm(g.descriptors_2d, f.descriptors_2d, cv::NORM_HAMMING), 0.0);
  ASSERT_EQ(g.line_p_C.size(), 1u);
  EXPECT_LT((g.line_uv[0][1] - f.line_uv[0][1]).norm(), 1e-7);
  EXPECT_LT((g.line_p_C[0][1] - f.line_p_C[0][1]).norm(), 1e-6);
  EXPECT_EQ(g.line_desc[0], f.line_desc[0]);
  // PlaceFeatures keeps double coordinates, the tracked corners' own copies and a second descriptor per 3D corner.
  const std::size_t full = f.uv.capacity() * sizeof(Vec2) + f.p_C.capacity() * sizeof(Vec3) +
                           static_cast<std::size_t>(f.descriptors_2d.rows + f.descriptors_3d.rows) * 32;
  EXPECT_LT(static_cast<double>(s.bytes()), 0.75 * static_cast<double>(full));
}

TEST(PlaceStore, KeepsTheTrackedCornersAndTheStrongestDetectedOnes) {
  const test::WallScene scene;
  const PlaceFeatures f = describedWall(scene, test::WallScene::cameraAt(Vec3(0.1, 0.0, 1.2), 0.02));
  const int tracked = static_cast<int>(f.tracked_rows.size());
  const int detected = static_cast<int>(f.uv.size()) - tracked;
  ASSERT_GT(detected, 40);
  const StoredPlace s = storePlace(f, 30);
  ASSERT_EQ(static_cast<int>(s.uv.size()), tracked + 30);
  EXPECT_LT(s.bytes(), storePlace(f).bytes());
  // The same 3D corners with the same descriptors; the kept 2D rows are the tracked ones and the first 30 others.
  const PlaceFeatures g = expandPlace(s);
  ASSERT_EQ(g.descriptors_3d.rows, f.descriptors_3d.rows);
  EXPECT_EQ(cv::norm(g.descriptors_3d, f.descriptors_3d, cv::NORM_HAMMING), 0.0);
  std::vector<bool> is_tracked(f.uv.size(), false);
  for (int r : f.tracked_rows) is_tracked[static_cast<std::size_t>(r)] = true;
  std::size_t out = 0;
  int others = 0;
  for (std::size_t r = 0; r < f.uv.size(); ++r) {
    if (!is_tracked[r] && others++ >= 30) continue;
    ASSERT_LT(out, g.uv.size());
    EXPECT_LT((g.uv[out] - f.uv[r]).norm(), 1e-7) << r;
    EXPECT_EQ(cv::norm(g.descriptors_2d.row(static_cast<int>(out)), f.descriptors_2d.row(static_cast<int>(r)),
                       cv::NORM_HAMMING), 0.0);
    ++out;
  }
  EXPECT_EQ(storePlace(f, -1).uv.size(), f.uv.size());
}

TEST(PlaceStore, KeepsItsOwnDescriptorsWhenTheRowsAreUnknown) {
  const test::WallScene scene;
  PlaceFeatures f = describedWall(scene, test::WallScene::cameraAt(Vec3(0.0, 0.0, 1.2), 0.0));
  f.rows_3d.clear();  // as a description put together by hand
  const PlaceFeatures g = expandPlace(storePlace(f));
  ASSERT_EQ(g.descriptors_3d.rows, f.descriptors_3d.rows);
  EXPECT_EQ(cv::norm(g.descriptors_3d, f.descriptors_3d, cv::NORM_HAMMING), 0.0);
}

TEST(PlaceStore, AStoredPlaceMatchesAsTheFullOne) {
  const test::WallScene scene;
  const Pose T_W_Cold = test::WallScene::cameraAt(Vec3(0.0, 0.0, 1.2), 0.0);
  const Pose T_W_Cnew = test::WallScene::cameraAt(Vec3(0.35, 0.4, 1.1), 0.12);
  const PlaceFeatures f_old = describedWall(scene, T_W_Cold);
  const PlaceFeatures f_new = describedWall(scene, T_W_Cnew);
  const PlaceMatch full = matchPlaces(f_old, f_new, PlaceMatchOptions{});
  const PlaceMatch stored = matchPlaces(expandPlace(storePlace(f_old)), f_new, PlaceMatchOptions{});
  ASSERT_TRUE(full.ok);
  ASSERT_TRUE(stored.ok);
  EXPECT_EQ(stored.inliers, full.inliers);
  EXPECT_LT((stored.T_Cold_Cnew.p - full.T_Cold_Cnew.p).norm(), 1e-4);
  EXPECT_LT(logSO3(stored.T_Cold_Cnew.q.conjugate() * full.T_Cold_Cnew.q).norm(), 1e-4);
}

}  // namespace
}  // namespace linnet
