// LineTracker on the real EuRoC micro snippet (V1_01_easy, 95 stereo frames, 752x480): counts and track lengths.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>

#include <opencv2/core/persistence.hpp>
#include <opencv2/imgcodecs.hpp>

#include "linnet/core/error.h"
#include "linnet/features/line_tracker.h"
#include "support/shared_data.h"

namespace linnet {
namespace {

// Reads intrinsics, radtan coefficients and T_BS from a EuRoC sensor.yaml (OpenCV's YAML reader is enough here).
CameraCalibration readSensorYaml(const std::filesystem::path& file) {
  cv::FileStorage fs(file.string(), cv::FileStorage::READ);
  CameraCalibration c;
  std::vector<double> T, intr, dist;
  fs["T_BS"]["data"] >> T;
  fs["intrinsics"] >> intr;
  fs["distortion_coefficients"] >> dist;
  if (T.size() != 16 || intr.size() != 4 || dist.size() != 4) throw InputError(file.string(), 0, "unexpected layout");
  Mat4 M;
  for (int k = 0; k < 16; ++k) M(k / 4, k % 4) = T[k];
  c.T_B_C = Pose::fromMatrix(M);
  for (int k = 0; k < 4; ++k) c.intrinsics[k] = intr[k];
  c.distortion = "radtan";
  c.distortion_coeffs = dist;
  return c;
}

std::vector<std::pair<Timestamp, std::string>> readImageList(const std::filesystem::path& cam_dir) {
  std::ifstream in(cam_dir / "data.csv");
  std::vector<std::pair<Timestamp, std::string>> list;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    const auto comma = line.find(',');
    std::string name = line.substr(comma + 1);
    while (!name.empty() && (name.back() == '\r' || name.back() == ' ')) name.pop_back();
    list.push_back({std::stoll(line.substr(0, comma)), (cam_dir / "data" / name).string()});
  }
  return list;
}

TEST(LineTrackerReal, EurocMicroTracksLines) {
  const auto root = linnet::testing::eurocMicroDir();
  LINNET_REQUIRE_SHARED_DATA(root);
  const auto mav = root / "mav0";
  const CameraCalibration c0 = readSensorYaml(mav / "cam0" / "sensor.yaml");
  const CameraCalibration c1 = readSensorYaml(mav / "cam1" / "sensor.yaml");
  const auto cam0 = CameraModel::create(c0), cam1 = CameraModel::create(c1);
  const Pose T_C1_C0 = c1.T_B_C.inverse() * c0.T_B_C;
  LineTracker tracker(LineTrackerOptions{}, *cam0, cam1.get(), T_C1_C0);
  const auto left = readImageList(mav / "cam0"), right = readImageList(mav / "cam1");
  ASSERT_EQ(left.size(), right.size());
  ASSERT_GE(left.size(), 90u);
  std::vector<int> per_frame, stereo, tracked;
  std::map<std::int64_t, int> length;
  std::vector<double> total_ms;
  std::vector<int> age;  // track length of every delivered observation
  for (std::size_t k = 0; k < left.size(); ++k) {
    ASSERT_EQ(left[k].first, right[k].first);
    const cv::Mat l = cv::imread(left[k].second, cv::IMREAD_GRAYSCALE), r = cv::imread(right[k].second, cv::IMREAD_GRAYSCALE);
    std::vector<LineObservation> obs;
    tracker.track(left[k].first, l, r, &obs);
    per_frame.push_back(static_cast<int>(obs.size()));
    stereo.push_back(tracker.lastTimings().stereo_matched);
    tracked.push_back(tracker.lastTimings().tracked);
    total_ms.push_back(tracker.lastTimings().total_ms);
    for (const LineObservation& o : obs) {
      length[o.id] = o.track_length;
      age.push_back(o.track_length);
      // A right observation keeps roughly the left one's direction (gate: 15 degrees in normalised coordinates).
      if (o.has_right) {
        EXPECT_GT((o.pe1 - o.ps1).normalized().dot((o.pe0 - o.ps0).normalized()), std::cos(20.0 * 3.14159265 / 180.0));
      }
    }
  }
  auto median = [](auto v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
  };
  std::vector<int> lengths;
  for (const auto& [id, len] : length) lengths.push_back(len);
  std::printf("  %zu frames: median %d lines/frame, %d with a right match, %d tracked from the previous frame\n",
              left.size(), median(per_frame), median(stereo), median(tracked));
  std::printf("  %zu ids; median final track length per id %d; median track length of delivered lines %d; "
              "median total %.2f ms/frame (wall, unpinned, under test load)\n",
              lengths.size(), median(lengths), median(age), median(total_ms));
  EXPECT_GE(median(per_frame), 50);
  EXPECT_GE(median(stereo), 25);
  EXPECT_GE(median(tracked), 40);
  EXPECT_GE(median(lengths), 10);
  EXPECT_GE(median(age), 20);
}

}  // namespace
}  // namespace linnet
