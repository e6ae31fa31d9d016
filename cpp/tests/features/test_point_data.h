// Test helpers of the point front-end: the EuRoC micro set read with OpenCV (the io layer is tested on its own).
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "linnet/camera/camera_model.h"
#include "linnet/core/error.h"

namespace linnet::testing {

/// A camera's sensor.yaml (OpenCV-readable %YAML:1.0 of EuRoC) -> CameraCalibration.
inline CameraCalibration readEurocCamera(const std::filesystem::path& sensor_yaml) {
  cv::FileStorage fs(sensor_yaml.string(), cv::FileStorage::READ);
  if (!fs.isOpened()) throw InputError(sensor_yaml.string(), 0, "cannot open");
  CameraCalibration c;
  std::vector<double> intr, dist, T;
  std::vector<int> res;
  fs["intrinsics"] >> intr;
  fs["distortion_coefficients"] >> dist;
  fs["resolution"] >> res;
  fs["T_BS"]["data"] >> T;
  if (intr.size() != 4 || res.size() != 2 || T.size() != 16) throw InputError(sensor_yaml.string(), 0, "bad camera");
  c.intrinsics = {intr[0], intr[1], intr[2], intr[3]};
  c.distortion_coeffs = dist;
  c.width = res[0];
  c.height = res[1];
  Mat4 M;
  for (int i = 0; i < 16; ++i) M(i / 4, i % 4) = T[static_cast<std::size_t>(i)];
  c.T_B_C = Pose::fromMatrix(M);
  return c;
}

struct StereoFrame {
  Timestamp t = 0;
  cv::Mat left, right;
};

/// The stereo frames of a EuRoC folder (time stamps of cam0; cam1 has the same file names), at most `max_frames`.
inline std::vector<StereoFrame> readEurocStereo(const std::filesystem::path& root, std::size_t max_frames = 100000) {
  const std::filesystem::path mav = root / "mav0";
  std::ifstream csv(mav / "cam0" / "data.csv");
  if (!csv) throw InputError((mav / "cam0" / "data.csv").string(), 0, "cannot open");
  std::vector<StereoFrame> frames;
  std::string line;
  while (std::getline(csv, line) && frames.size() < max_frames) {
    if (line.empty() || line[0] == '#') continue;
    const auto comma = line.find(',');
    StereoFrame f;
    f.t = std::stoll(line.substr(0, comma));
    std::string name = line.substr(comma + 1);
    while (!name.empty() && (name.back() == '\r' || name.back() == ' ')) name.pop_back();
    f.left = cv::imread((mav / "cam0" / "data" / name).string(), cv::IMREAD_GRAYSCALE);
    f.right = cv::imread((mav / "cam1" / "data" / name).string(), cv::IMREAD_GRAYSCALE);
    if (f.left.empty() || f.right.empty()) throw InputError(name, 0, "cannot read the stereo pair");
    frames.push_back(std::move(f));
  }
  return frames;
}

}  // namespace linnet::testing
