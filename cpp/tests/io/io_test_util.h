// Helpers of the io tests: per-process temp folders that clean up after themselves, and small EuRoC copies.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <utility>

#include "support/shared_data.h"

namespace linnet::io_test {

/// A fresh folder <tmp>/linnet_io_<pid>_<name> (unique per test process, so parallel runs do not collide),
/// removed with everything in it when the object goes away.
class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() /
              ("linnet_io_" + std::to_string(::getpid()) + "_" + name)) {
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) std::filesystem::remove_all(path_, ec);
  }
  TempDir(TempDir&& o) noexcept : path_(std::exchange(o.path_, {})) {}
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  TempDir& operator=(TempDir&&) = delete;

  const std::filesystem::path& path() const { return path_; }
  operator const std::filesystem::path&() const { return path_; }  // NOLINT: used like a path
  std::filesystem::path operator/(const std::string& s) const { return path_ / s; }
  std::string string() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

/// The first `rows` lines of a text file (its header included).
inline std::string headLines(const std::filesystem::path& p, int rows) {
  std::ifstream in(p);
  std::string out, line;
  for (int i = 0; i < rows && std::getline(in, line); ++i) out += line + "\n";
  return out;
}

inline void writeFile(const std::filesystem::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

/// Copies the first `frames` stereo frames of the micro set (images as symlinks), the first `imu_rows` IMU
/// rows and the first `gt_rows` ground-truth rows (0: no ground truth) into <root>/mav0, with the sensor.yaml
/// files when `sensor_yamls` (imu0/sensor.yaml is always copied).
inline void copyEurocSubset(const std::filesystem::path& root, int frames, int imu_rows, int gt_rows,
                            bool sensor_yamls) {
  namespace fs = std::filesystem;
  const fs::path src = testing::eurocMicroDir() / "mav0";
  const fs::path dst = root / "mav0";
  for (const char* cam : {"cam0", "cam1"}) {
    fs::create_directories(dst / cam / "data");
    if (sensor_yamls) fs::copy_file(src / cam / "sensor.yaml", dst / cam / "sensor.yaml");
    const std::string csv = headLines(src / cam / "data.csv", frames + 1);
    writeFile(dst / cam / "data.csv", csv);
    std::size_t pos = csv.find('\n') + 1;  // skip the header
    while (pos < csv.size()) {
      const std::size_t end = csv.find('\n', pos);
      const std::string line = csv.substr(pos, end - pos);
      const std::string file = line.substr(line.find(',') + 1);
      fs::create_symlink(src / cam / "data" / file, dst / cam / "data" / file);
      pos = end + 1;
    }
  }
  fs::create_directories(dst / "imu0");
  fs::copy_file(src / "imu0" / "sensor.yaml", dst / "imu0" / "sensor.yaml");
  writeFile(dst / "imu0" / "data.csv", headLines(src / "imu0" / "data.csv", imu_rows + 1));
  if (gt_rows > 0) {
    fs::create_directories(dst / "state_groundtruth_estimate0");
    writeFile(dst / "state_groundtruth_estimate0" / "data.csv",
              headLines(src / "state_groundtruth_estimate0" / "data.csv", gt_rows + 1));
  }
}

}  // namespace linnet::io_test
